#pragma once
// Vectors for large outputs: sized without being written, so that their pages are first touched by the threads that
// fill them rather than by one thread zeroing them, and, from 2 MB on, on 2 MB pages where the system offers
// them (Linux's transparent huge pages), so that first touching costs one fault per 2 MB instead of one per 4 KB.

#include <cstddef>
#include <limits>
#include <memory>
#include <new>
#include <utility>
#include <vector>

namespace specula {

namespace detail {
/// Blocks of at least this many bytes are large: allocate_large's.
inline constexpr std::size_t kLargeBlock = std::size_t(1) << 21;
/// bytes (>= 1) rounded up to whole 2 MB pages, 2 MB aligned, advised to the kernel as huge pages; std::bad_alloc
/// when the memory is not there. Freed by release_large.
void* allocate_large(std::size_t bytes);
/// Frees a block of allocate_large (nullptr: nothing).
void release_large(void* p) noexcept;
}  // namespace detail

/// std::allocator whose construction without arguments default-initialises (trivial elements are left unwritten),
/// and whose blocks of detail::kLargeBlock bytes or more come from detail::allocate_large.
template <class T>
struct NoInitAllocator : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = NoInitAllocator<U>;
  };
  NoInitAllocator() = default;
  template <class U>
  NoInitAllocator(const NoInitAllocator<U>&) noexcept {}
  T* allocate(std::size_t n) {
    if (n < detail::kLargeBlock / sizeof(T)) return std::allocator<T>::allocate(n);
    if (n > std::numeric_limits<std::size_t>::max() / sizeof(T)) throw std::bad_array_new_length();
    return static_cast<T*>(detail::allocate_large(n * sizeof(T)));
  }
  void deallocate(T* p, std::size_t n) noexcept {
    if (n < detail::kLargeBlock / sizeof(T))
      std::allocator<T>::deallocate(p, n);
    else
      detail::release_large(p);
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    if constexpr (sizeof...(Args) == 0)
      ::new (static_cast<void*>(p)) U;
    else
      ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

/// A vector whose resize(n) leaves new trivial elements unwritten, large ones on huge pages; assign and
/// resize(n, v) still write.
template <class T>
using Buffer = std::vector<T, NoInitAllocator<T>>;

}  // namespace specula
