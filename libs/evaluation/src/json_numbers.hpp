// metrics.json numbers (internal to the evaluation library): a figure that could not be
// computed is written as null, and read back as NaN.
#pragma once

#include <cmath>
#include <nlohmann/json.hpp>

namespace uwbloc::eval {

/// JSON numbers must be finite: a non-finite value is written as null.
inline nlohmann::json jsonNumber(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

/// The number under `key`, NaN when it is missing or null.
inline double jsonNum(const nlohmann::json& j, const char* key) {
  const auto it = j.find(key);
  return it == j.end() || !it->is_number() ? NAN : it->get<double>();
}

}  // namespace uwbloc::eval
