// Bad user input: the message names the file, and the line or field where it can.
#pragma once

#include <stdexcept>
#include <string>

namespace uwbloc::data {

class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// "file:line: message" (line omitted when 0).
[[noreturn]] void throwInputError(const std::string& file, int line, const std::string& message);

}  // namespace uwbloc::data
