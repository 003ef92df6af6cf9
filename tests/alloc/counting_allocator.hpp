#pragma once

// A test-only global allocation counter: this binary replaces operator new/delete (and, outside
// sanitizer builds, malloc/calloc/realloc through glibc's __libc_* entry points), so a test can
// assert that a per-frame call performs no heap allocation at all.

#include <cstddef>

namespace epitrack::test {

/// Number of allocations (operator new + malloc family) since the program started.
std::size_t allocationCount();

/// Counts allocations made inside its lifetime.
class AllocationScope {
 public:
  AllocationScope() : start_(allocationCount()) {}
  [[nodiscard]] std::size_t count() const { return allocationCount() - start_; }

 private:
  std::size_t start_;
};

/// True when malloc itself is hooked too (not under AddressSanitizer).
bool mallocIsCounted();

}  // namespace epitrack::test
