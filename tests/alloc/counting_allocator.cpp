#include "tests/alloc/counting_allocator.hpp"

#include <atomic>
#include <cstdlib>
#include <new>

#if defined(__SANITIZE_ADDRESS__)
#define EPITRACK_COUNT_MALLOC 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(memory_sanitizer) || \
    __has_feature(thread_sanitizer)
#define EPITRACK_COUNT_MALLOC 0
#endif
#endif
#ifndef EPITRACK_COUNT_MALLOC
#define EPITRACK_COUNT_MALLOC 1
#endif

namespace {
std::atomic<std::size_t> g_count{0};
}

namespace epitrack::test {
std::size_t allocationCount() { return g_count.load(std::memory_order_relaxed); }
bool mallocIsCounted() { return EPITRACK_COUNT_MALLOC != 0; }
}  // namespace epitrack::test

#if EPITRACK_COUNT_MALLOC
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void __libc_free(void*);

void* malloc(std::size_t n) {
  g_count.fetch_add(1, std::memory_order_relaxed);
  return __libc_malloc(n);
}
void* calloc(std::size_t a, std::size_t b) {
  g_count.fetch_add(1, std::memory_order_relaxed);
  return __libc_calloc(a, b);
}
void* realloc(void* p, std::size_t n) {
  g_count.fetch_add(1, std::memory_order_relaxed);
  return __libc_realloc(p, n);
}
void free(void* p) { __libc_free(p); }
}
#endif

namespace {
void* countedAlloc(std::size_t n, std::size_t align) {
  g_count.fetch_add(1, std::memory_order_relaxed);
#if EPITRACK_COUNT_MALLOC
  void* p = align <= alignof(std::max_align_t) ? __libc_malloc(n == 0 ? 1 : n)
                                               : __libc_memalign(align, n == 0 ? 1 : n);
#else
  void* p = align <= alignof(std::max_align_t)
                ? std::malloc(n == 0 ? 1 : n)
                : std::aligned_alloc(align, (n + align - 1) / align * align);
#endif
  if (p == nullptr) throw std::bad_alloc();
  return p;
}
void countedFree(void* p) {
#if EPITRACK_COUNT_MALLOC
  __libc_free(p);
#else
  std::free(p);
#endif
}
}  // namespace

void* operator new(std::size_t n) { return countedAlloc(n, 0); }
void* operator new[](std::size_t n) { return countedAlloc(n, 0); }
void* operator new(std::size_t n, std::align_val_t a) {
  return countedAlloc(n, static_cast<std::size_t>(a));
}
void* operator new[](std::size_t n, std::align_val_t a) {
  return countedAlloc(n, static_cast<std::size_t>(a));
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return countedAlloc(n, 0);
  } catch (...) {
    return nullptr;
  }
}
void operator delete(void* p) noexcept { countedFree(p); }
void operator delete[](void* p) noexcept { countedFree(p); }
void operator delete(void* p, std::size_t) noexcept { countedFree(p); }
void operator delete[](void* p, std::size_t) noexcept { countedFree(p); }
void operator delete(void* p, std::align_val_t) noexcept { countedFree(p); }
void operator delete[](void* p, std::align_val_t) noexcept { countedFree(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { countedFree(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { countedFree(p); }
