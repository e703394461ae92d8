#include "uwbloc/localization/params.hpp"

#include <algorithm>

namespace uwbloc::loc {

ParamSet ParamSet::parse(const std::string& text, const std::string& context) {
  ParamSet set;
  set.context_ = context;
  std::string item;
  std::istringstream in(text);
  while (std::getline(in, item, ',')) {
    if (item.empty()) continue;
    const auto eq = item.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == item.size())
      throw ParamError(context + ": expected key=value, got '" + item + "'");
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
