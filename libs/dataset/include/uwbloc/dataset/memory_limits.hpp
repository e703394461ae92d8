// The memory a run may use, and a cap on the bytes allocated on the calling thread, for code that
// sizes its buffers from untrusted bytes (MRPT's deserialiser reads a count and resizes before it
// reads the elements: a corrupt count of 4e9 would otherwise allocate gigabytes).
//
// The cap takes effect only in an executable that links the allocation guard
// (`uwbloc_allocation_guard`: the global operator new/delete over malloc/free, checking the cap).
// The uwbloc executables, tests and fuzz targets link it; a program that embeds the libraries
// keeps its own allocator, and the cap is then a no-op (`allocationGuardActive()` says which).
#pragma once

#include <cstddef>
#include <new>
#include <optional>
#include <string>

namespace uwbloc::data {

/// The memory budget of a run in bytes: what `--max-memory` sets. By default half of the
/// machine's physical memory (4 GiB when it cannot be read).
std::size_t memoryBudget() noexcept;
void setMemoryBudget(std::size_t bytes) noexcept;

/// Parses a size such as "512M", "4G", "1.5GiB" or "2000000" (bytes); nullopt when malformed.
std::optional<std::size_t> parseByteSize(const std::string& text);

/// "1.5 GiB", "300 MiB", "12 KiB", "17 B".
std::string formatBytes(double bytes);

/// Charges `bytes` to the calling thread's cap (called by the guard for every allocation):
/// false, and the request remembered, when the bytes allocated under the current cap would
/// exceed it. Always true when no cap is set.
bool chargeAllocation(std::size_t bytes) noexcept;

/// What the guard throws for an allocation over the cap.
class AllocationOverCap : public std::bad_alloc {
 public:
  const char* what() const noexcept override { return "allocation over the cap"; }
};

/// Caps the bytes allocated on the calling thread (the sum of the requests, frees not
/// subtracted) for the lifetime of the object, restoring the previous cap after it.
class ScopedAllocationCap {
 public:
  explicit ScopedAllocationCap(std::size_t bytes) noexcept;
  ~ScopedAllocationCap();
  ScopedAllocationCap(const ScopedAllocationCap&) = delete;
  ScopedAllocationCap& operator=(const ScopedAllocationCap&) = delete;

  /// The bytes allocated under this cap so far, and the request refused (0 when none was).
  std::size_t used() const noexcept;
  std::size_t refused() const noexcept;

 private:
  std::size_t previous_cap_, previous_used_, previous_refused_;
};

/// True when this executable links the guard (probed once: a 1-byte cap refuses 64 bytes).
bool allocationGuardActive();

}  // namespace uwbloc::data
