#include "specula/core/buffer.h"

#include <cstdint>
#include <cstdlib>

#include "specula/core/huge_pages.h"

namespace specula::detail {

namespace {
constexpr std::size_t kHugePage = kHugePageBytes;
// The block handed out starts at the first 2 MB boundary after a slot holding malloc's pointer.
constexpr std::size_t kSlack = kHugePage + sizeof(void*);
}  // namespace

// A plain malloc of the rounded size plus the slack rather than aligned_alloc: glibc's aligned allocation asks for
// the alignment on top of the size, so a block freed and asked for again never fits its own hole and every call
// takes (and first touches) fresh pages; a plain malloc of the same size gets the freed block back, its pages
// already there.
void* allocate_large(std::size_t bytes) {
  if (bytes == 0 || bytes > std::numeric_limits<std::size_t>::max() - 2 * kSlack) throw std::bad_alloc();
  const std::size_t size = (bytes + kHugePage - 1) / kHugePage * kHugePage;
  void* raw = std::malloc(size + kSlack);
  if (!raw) throw std::bad_alloc();
  const std::uintptr_t first = (reinterpret_cast<std::uintptr_t>(raw) + kSlack - 1) / kHugePage * kHugePage;
  void* p = reinterpret_cast<void*>(first);
  static_cast<void**>(p)[-1] = raw;
  advise_huge_pages(p, size);
  return p;
}

void release_large(void* p) noexcept {
  if (p) std::free(static_cast<void**>(p)[-1]);
}

}  // namespace specula::detail
