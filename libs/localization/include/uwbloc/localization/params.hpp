// Method parameters: "key=value" pairs from a method spec ("uwb-kf:q=0.05,r=0.1") or an INI
// section, loaded into a component's Params struct. Each Params struct lists its fields once,
// in a visit() member, and that one list serves loading, printing and `uwbloc methods`.
#pragma once

#include <iosfwd>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

namespace uwbloc::loc {

struct ParamInfo {
  std::string key;
  std::string value;  ///< default (in a description) or effective value (after loading)
  std::string help;
};

/// A user's token for an error message: at most 80 characters (longer ones end in "..."), control
/// characters escaped, so that a message stays one readable line whatever the input held.
std::string quoteToken(const std::string& token);

/// Bad user input about methods or parameters.
class ParamError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One named value of an enum parameter. An enum becomes a parameter by declaring, beside it,
///   constexpr std::array<EnumName<E>, N> enumNames(E) { return {{{E::kA, "a"}, ...}}; }
/// (found by argument-dependent lookup); its text is then parsed once, when the method is built,
/// and an unknown name is an error that lists the known ones.
template <class E>
struct EnumName {
  E value;
  const char* name;
};

/// The name of an enum value ("?" when it has none).
template <class E>
const char* enumName(E value) {
  for (const auto& n : enumNames(E{}))
    if (n.value == value) return n.name;
  return "?";
}

/// "a, b or c": the known names of an enum.
template <class E>
std::string enumChoices() {
  std::string out;
  const auto names = enumNames(E{});
  for (size_t i = 0; i < names.size(); ++i)
    out += std::string(i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + names[i].name;
  return out;
}

/// A number that may be left to the data: "auto" (estimated from the recording while it runs)
/// or a value.
struct AutoDouble {
  std::optional<double> value;  ///< empty: auto
  bool isAuto() const { return !value.has_value(); }
};
std::istream& operator>>(std::istream& in, AutoDouble& v);
std::ostream& operator<<(std::ostream& out, const AutoDouble& v);

class ParamSet {
 public:
  ParamSet() = default;
  /// Parses "k=v,k=v"; throws ParamError naming the malformed item.
  static ParamSet parse(const std::string& text, const std::string& context);
  void set(const std::string& key, const std::string& value) { values_[key] = value; }
  bool has(const std::string& key) const { return values_.count(key) != 0; }
  /// Copies every key of `other` over this set's values.
  void merge(const ParamSet& other) {
    for (const auto& [k, v] : other.values_) values_[k] = v;
  }
  bool empty() const { return values_.empty(); }

  /// Reads `key` into `value` when present (marking it used); throws ParamError on a value of
  /// the wrong type.
  template <class T>
  void read(const std::string& key, T& value) {
    auto it = values_.find(key);
    if (it == values_.end()) return;
    used_.push_back(key);
    if constexpr (std::is_enum_v<T>) {
      for (const auto& n : enumNames(T{}))
        if (it->second == n.name) {
          value = n.value;
          return;
        }
      throw ParamError(context_ + ": parameter '" + key + "' must be " + enumChoices<T>() +
                       ", got " + quoteToken(it->second));
    } else {
      std::istringstream in(it->second);
      T parsed{};
      in >> parsed;
      if (in.fail() || !(in >> std::ws).eof())
        throw ParamError(context_ + ": parameter '" + key + "' has invalid value " +
                         quoteToken(it->second));
      value = parsed;
    }
  }
  /// Throws ParamError listing keys that no field read.
  void checkAllUsed(const std::vector<std::string>& known) const;
  const std::string& context() const { return context_; }
  void setContext(const std::string& c) { context_ = c; }

 private:
  std::map<std::string, std::string> values_;
  std::vector<std::string> used_;
  std::string context_;
};

template <>
inline void ParamSet::read<std::string>(const std::string& key, std::string& value) {
  auto it = values_.find(key);
  if (it == values_.end()) return;
  used_.push_back(key);
  value = it->second;
}

template <>
inline void ParamSet::read<bool>(const std::string& key, bool& value) {
  auto it = values_.find(key);
  if (it == values_.end()) return;
  used_.push_back(key);
  const std::string& v = it->second;
  if (v == "1" || v == "true" || v == "on" || v == "yes") {
    value = true;
  } else if (v == "0" || v == "false" || v == "off" || v == "no") {
    value = false;
  } else {
    throw ParamError(context_ + ": parameter '" + key + "' expects a boolean, got '" + v + "'");
  }
}

namespace detail {
template <class T>
std::string formatValue(const T& v) {
  if constexpr (std::is_enum_v<T>) {
    return enumName(v);
  } else {
    std::ostringstream out;
    out << v;
    return out.str();
  }
}
inline std::string formatValue(bool v) { return v ? "1" : "0"; }
}  // namespace detail

/// The range a numeric parameter must lie in, by key: one table for every method (limits.cpp),
/// printed by `uwbloc methods --limits`.
struct ParamLimit {
  const char* key;
  double min, max;
  bool min_exclusive;  ///< the value must be above min, not equal to it
  const char* why;
};
const std::vector<ParamLimit>& paramLimits();

/// Throws ParamError when `value` is not finite or outside its key's limits (context names the
/// method). Values of other types have nothing to check.
void checkLimit(const std::string& context, const std::string& key, double value);
inline void checkLimit(const std::string& context, const std::string& key, int value) {
  checkLimit(context, key, static_cast<double>(value));
}
inline void checkLimit(const std::string& context, const std::string& key, const AutoDouble& v) {
  if (v.value) checkLimit(context, key, *v.value);
}
template <class T>
void checkLimit(const std::string&, const std::string&, const T&) {}

/// Loads every field a Params struct visits from `set`, then rejects unknown keys.
template <class P>
void loadParams(ParamSet& set, P& params) {
  std::vector<std::string> known;
  params.visit([&](const char* key, auto& field, const char*) {
    set.read(key, field);
    checkLimit(set.context(), key, field);
    known.emplace_back(key);
  });
  set.checkAllUsed(known);
}

/// Lists a Params struct's fields with their current values and help text.
template <class P>
std::vector<ParamInfo> describeParams(P params) {
  std::vector<ParamInfo> out;
  params.visit([&](const char* key, auto& field, const char* help) {
    out.push_back({key, detail::formatValue(field), help});
  });
  return out;
}

}  // namespace uwbloc::loc
