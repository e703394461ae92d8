#include "uwbloc/dataset/memory_limits.hpp"

#include <unistd.h>

#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <memory>

namespace uwbloc::data {

namespace {
thread_local std::size_t t_cap = 0, t_used = 0, t_refused = 0;

std::size_t defaultBudget() {
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  if (pages <= 0 || page <= 0) return std::size_t{4} << 30;
  return static_cast<std::size_t>(pages) * static_cast<std::size_t>(page) / 2;
}

std::atomic<std::size_t>& budget() {
  static std::atomic<std::size_t> value{defaultBudget()};
  return value;
}

}  // namespace

std::size_t memoryBudget() noexcept { return budget().load(); }
void setMemoryBudget(std::size_t bytes) noexcept { budget().store(bytes); }

std::optional<std::size_t> parseByteSize(const std::string& text) {
  size_t used = 0;
  double value = 0;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    return std::nullopt;
  }
  std::string unit = text.substr(used);
  for (auto& c : unit) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  if (unit.size() > 1 && unit.back() == 'B') unit.pop_back();
  if (unit.size() > 1 && unit.back() == 'I') unit.pop_back();
  double scale = 1;
  if (unit == "K")
    scale = 1024.0;
  else if (unit == "M")
    scale = 1024.0 * 1024;
  else if (unit == "G")
    scale = 1024.0 * 1024 * 1024;
  else if (unit == "T")
    scale = 1024.0 * 1024 * 1024 * 1024;
  else if (!unit.empty() && unit != "B")
    return std::nullopt;
  const double bytes = value * scale;
  if (!std::isfinite(bytes) || bytes < 1 || bytes > 1e18) return std::nullopt;
  return static_cast<std::size_t>(bytes);
}

std::string formatBytes(double bytes) {
  static const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (bytes >= 1024 && u < 4) {
    bytes /= 1024;
    ++u;
  }
  char text[32];
  std::snprintf(text, sizeof text, u == 0 ? "%.0f %s" : "%.3g %s", bytes, units[u]);
  return text;
}

bool chargeAllocation(std::size_t bytes) noexcept {
  if (t_cap == 0) return true;
  if (bytes > t_cap - t_used) {
    t_refused = bytes;
    return false;
  }
  t_used += bytes;
  return true;
}

ScopedAllocationCap::ScopedAllocationCap(std::size_t bytes) noexcept
    : previous_cap_(t_cap), previous_used_(t_used), previous_refused_(t_refused) {
  t_cap = bytes;
  t_used = 0;
  t_refused = 0;
}

ScopedAllocationCap::~ScopedAllocationCap() {
  t_cap = previous_cap_;
  t_used = previous_used_;
  t_refused = previous_refused_;
}

std::size_t ScopedAllocationCap::used() const noexcept { return t_used; }
std::size_t ScopedAllocationCap::refused() const noexcept { return t_refused; }

bool allocationGuardActive() {
  static const bool active = [] {
    ScopedAllocationCap cap(1);
    try {
      // A direct call: a new-expression whose result is unused may be elided.
      ::operator delete(::operator new(64));
      return false;
    } catch (const AllocationOverCap&) {
      return true;
    }
  }();
  return active;
}

}  // namespace uwbloc::data
