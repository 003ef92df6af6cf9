// LD_PRELOAD library for the VM checks (tools/vm/checks.sh): counts every heap allocation of a
// program (malloc, calloc, realloc, memalign family) and prints the total to standard error at
// exit as "alloc_count: N". The checks run the same command for two frame counts: equal totals
// mean no allocation per frame. glibc's __libc_* entry points do the work, so nothing here calls
// dlsym (which may itself allocate) and the counter is ready before the first allocation.
#include <stdatomic.h>
#include <stddef.h>
#include <stdio.h>
#include <unistd.h>

void* __libc_malloc(size_t size);
void* __libc_calloc(size_t count, size_t size);
void* __libc_realloc(void* ptr, size_t size);
void* __libc_memalign(size_t alignment, size_t size);

static atomic_long g_allocations;

void* malloc(size_t size) {
  atomic_fetch_add(&g_allocations, 1);
  return __libc_malloc(size);
}

void* calloc(size_t count, size_t size) {
  atomic_fetch_add(&g_allocations, 1);
  return __libc_calloc(count, size);
}

void* realloc(void* ptr, size_t size) {
  atomic_fetch_add(&g_allocations, 1);
  return __libc_realloc(ptr, size);
}

void* memalign(size_t alignment, size_t size) {
  atomic_fetch_add(&g_allocations, 1);
  return __libc_memalign(alignment, size);
}

void* aligned_alloc(size_t alignment, size_t size) { return memalign(alignment, size); }

int posix_memalign(void** out, size_t alignment, size_t size) {
  void* p = memalign(alignment, size);
  if (p == NULL) return 12;  // ENOMEM
  *out = p;
  return 0;
}

// Written with write(2) into a stack buffer: stdio may allocate, and the count must not move.
__attribute__((destructor)) static void reportAllocations(void) {
  char line[64];
  const int n = snprintf(line, sizeof(line), "alloc_count: %ld\n", atomic_load(&g_allocations));
  if (n > 0) (void)!write(2, line, (size_t)n);
}
