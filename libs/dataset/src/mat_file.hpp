// MATLAB .mat files through libmatio: one numeric matrix by name.
#pragma once

#include <string>
#include <vector>

namespace uwbloc::data {

/// The rows of the real, dense, two-dimensional numeric variable `name` of a .mat file (any
/// version libmatio reads). Throws InputError naming the file and the variable when the file
/// cannot be read, or the variable is missing or not such a matrix.
std::vector<std::vector<double>> readMatMatrix(const std::string& path, const std::string& name);

}  // namespace uwbloc::data
