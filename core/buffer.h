#pragma once
// Vectors that can be sized without being written, so that a large output's pages are first touched by the threads
// that fill it rather than by one thread zeroing it.

#include <memory>
#include <new>
#include <utility>
#include <vector>

namespace specula {

/// std::allocator whose construction without arguments default-initialises: trivial elements are left unwritten.
template <class T>
struct NoInitAllocator : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = NoInitAllocator<U>;
  };
  NoInitAllocator() = default;
  template <class U>
  NoInitAllocator(const NoInitAllocator<U>&) noexcept {}
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    if constexpr (sizeof...(Args) == 0)
      ::new (static_cast<void*>(p)) U;
    else
      ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

/// A vector whose resize(n) leaves new trivial elements unwritten; assign and resize(n, v) still write.
template <class T>
using Buffer = std::vector<T, NoInitAllocator<T>>;

}  // namespace specula
