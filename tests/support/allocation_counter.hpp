#pragma once
// Counts heap allocations made through malloc, calloc, realloc, the aligned allocators and every
// form of operator new, in any thread. Eigen allocates with malloc, the standard library with
// operator new, so both are hooked. Linked only into binaries that are not built with
// AddressSanitizer or ThreadSanitizer (those replace the allocator themselves).

namespace allocation_counter {

/// Allocations since the program started.
long count() noexcept;

/// Allocations made while an instance lives.
class Scope {
 public:
  Scope() noexcept : start_(count()) {}
  long allocations() const noexcept { return count() - start_; }

 private:
  long start_;
};

}  // namespace allocation_counter
