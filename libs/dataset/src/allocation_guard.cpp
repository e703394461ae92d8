// The allocation guard: the replaceable global allocation functions ([new.delete]) over
// malloc/free, refusing a request that would take the calling thread over its cap
// (memory_limits.hpp). Linked into the uwbloc executables only, never into the installed libraries.
//
// It also stands in for MRPT's aligned allocation (mrpt/core/aligned_allocator.h), which its
// matrices and scans use and which bypasses operator new: the same cap applies, and a failed
// allocation throws std::bad_alloc instead of returning the null pointer that MRPT's
// aligned_allocator_cpp11 would write through (a corrupt dimension in a rawlog would otherwise
// crash the reader). The executable's definition takes precedence over libmrpt-core's for the
// MRPT libraries that call it.
#include <cstdlib>
#include <cstring>
#include <new>

#include "uwbloc/dataset/memory_limits.hpp"

namespace {

void* allocate(std::size_t n) {
  if (!uwbloc::data::chargeAllocation(n)) throw uwbloc::data::AllocationOverCap();
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}

void* allocateAligned(std::size_t n, std::align_val_t al) {
  if (!uwbloc::data::chargeAllocation(n)) throw uwbloc::data::AllocationOverCap();
  const auto a = static_cast<std::size_t>(al);
  const std::size_t rounded = ((n == 0 ? 1 : n) + a - 1) / a * a;  // aligned_alloc's contract
  if (void* p = std::aligned_alloc(a, rounded)) return p;
  throw std::bad_alloc();
}

template <typename F>
void* noThrow(F&& f) noexcept {
  try {
    return f();
  } catch (...) {
    return nullptr;
  }
}

}  // namespace

void* operator new(std::size_t n) { return allocate(n); }
void* operator new[](std::size_t n) { return allocate(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  return noThrow([n] { return allocate(n); });
}
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept {
  return noThrow([n] { return allocate(n); });
}
void* operator new(std::size_t n, std::align_val_t al) { return allocateAligned(n, al); }
void* operator new[](std::size_t n, std::align_val_t al) { return allocateAligned(n, al); }
void* operator new(std::size_t n, std::align_val_t al, const std::nothrow_t&) noexcept {
  return noThrow([n, al] { return allocateAligned(n, al); });
}
void* operator new[](std::size_t n, std::align_val_t al, const std::nothrow_t&) noexcept {
  return noThrow([n, al] { return allocateAligned(n, al); });
}

void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }

namespace mrpt {

void* aligned_malloc(std::size_t size, std::size_t alignment) {
  return allocateAligned(size, static_cast<std::align_val_t>(alignment));
}

void* aligned_calloc(std::size_t bytes, std::size_t alignment) {
  void* p = allocateAligned(bytes, static_cast<std::align_val_t>(alignment));
  std::memset(p, 0, bytes);
  return p;
}

}  // namespace mrpt
