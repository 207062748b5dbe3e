#include "testing/alloc_count.h"

#include <dlfcn.h>

#include <atomic>
#include <cstddef>
#include <cstdlib>
#include <new>

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define SSIU_ALLOC_COUNT_ASAN 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define SSIU_ALLOC_COUNT_ASAN 1
#endif

namespace {
std::atomic<long> g_count{0}, g_bytes{0}, g_throws{0};
void Note(std::size_t n) {
  g_count.fetch_add(1, std::memory_order_relaxed);
  g_bytes.fetch_add(static_cast<long>(n), std::memory_order_relaxed);
}
}  // namespace

#if !defined(SSIU_ALLOC_COUNT_ASAN) && defined(__GLIBC__)
// glibc's own entry points: an executable's malloc interposes on every library's calls to it.
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* malloc(std::size_t n) {
  Note(n);
  return __libc_malloc(n);
}
void* calloc(std::size_t k, std::size_t n) {
  Note(k * n);
  return __libc_calloc(k, n);
}
void* realloc(void* p, std::size_t n) {
  Note(n);
  return __libc_realloc(p, n);
}
}
#define SSIU_ALLOC_COUNT_MALLOC 1
#endif

namespace {
void* CountedNew(std::size_t n) {
#ifndef SSIU_ALLOC_COUNT_MALLOC
  Note(n);  // otherwise malloc counts it
#endif
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* CountedNewAligned(std::size_t n, std::size_t align) {
  Note(n);
  void* p = nullptr;
  if (posix_memalign(&p, align < sizeof(void*) ? sizeof(void*) : align, n ? n : 1) != 0) throw std::bad_alloc();
  return p;
}
}  // namespace

void* operator new(std::size_t n) { return CountedNew(n); }
void* operator new[](std::size_t n) { return CountedNew(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return CountedNew(n);
  } catch (...) {
    return nullptr;
  }
}
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return CountedNew(n);
  } catch (...) {
    return nullptr;
  }
}
void* operator new(std::size_t n, std::align_val_t a) { return CountedNewAligned(n, static_cast<std::size_t>(a)); }
void* operator new[](std::size_t n, std::align_val_t a) { return CountedNewAligned(n, static_cast<std::size_t>(a)); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }

// Every throw goes through the C++ runtime's __cxa_throw: counted, then handed to the real one.
extern "C" [[noreturn]] void __cxa_throw(void* object, void* type, void (*destroy)(void*)) {
  using Throw = void (*)(void*, void*, void (*)(void*));
  static const Throw real = reinterpret_cast<Throw>(dlsym(RTLD_NEXT, "__cxa_throw"));
  g_throws.fetch_add(1, std::memory_order_relaxed);
  real(object, type, destroy);
  __builtin_unreachable();
}

namespace ssiu::testing {

bool CountsMalloc() {
#ifdef SSIU_ALLOC_COUNT_MALLOC
  return true;
#else
  return false;
#endif
}

AllocationCounter::AllocationCounter() { Reset(); }
long AllocationCounter::Count() const { return g_count.load() - count0_; }
long AllocationCounter::Bytes() const { return g_bytes.load() - bytes0_; }
long AllocationCounter::Exceptions() const { return g_throws.load() - throws0_; }
void AllocationCounter::Reset() {
  count0_ = g_count.load();
  bytes0_ = g_bytes.load();
  throws0_ = g_throws.load();
}

}  // namespace ssiu::testing
