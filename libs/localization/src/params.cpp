#include "uwbloc/localization/params.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <istream>
#include <ostream>

namespace uwbloc::loc {

std::string quoteToken(const std::string& token) {
  std::string out = "'";
  size_t shown = 0;
  for (const char c : token) {
    if (shown == 80) {
      out += "...";
      break;
    }
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", u);
      out += buf;
    } else {
      out += c;
    }
    ++shown;
  }
  return out + "'";
}

std::istream& operator>>(std::istream& in, AutoDouble& v) {
  std::string token;
  if (!(in >> token)) return in;
  if (token == "auto") {
    v.value.reset();
    return in;
  }
  char* end = nullptr;
  const double x = std::strtod(token.c_str(), &end);
  if (end != token.c_str() + token.size() || !std::isfinite(x))
    in.setstate(std::ios::failbit);
  else
    v.value = x;
  return in;
}

std::ostream& operator<<(std::ostream& out, const AutoDouble& v) {
  if (v.value)
    out << *v.value;
  else
    out << "auto";
  return out;
}

ParamSet ParamSet::parse(const std::string& text, const std::string& context) {
  ParamSet set;
  set.context_ = context;
  std::string item;
  std::istringstream in(text);
  while (std::getline(in, item, ',')) {
    if (item.empty()) continue;
    const auto eq = item.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == item.size())
      throw ParamError(context + ": expected key=value, got " + quoteToken(item));
    set.values_[item.substr(0, eq)] = item.substr(eq + 1);
  }
  return set;
}

void ParamSet::checkAllUsed(const std::vector<std::string>& known) const {
  std::string unknown;
  for (const auto& [key, value] : values_) {
    if (std::find(known.begin(), known.end(), key) == known.end())
      unknown += (unknown.empty() ? "" : ", ") + key;
  }
  if (unknown.empty()) return;
  std::string list;
  for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
  throw ParamError(context_ + ": unknown parameter(s) " + unknown +
                   (list.empty() ? " (this method takes none)" : " (known: " + list + ")"));
}

}  // namespace uwbloc::loc
