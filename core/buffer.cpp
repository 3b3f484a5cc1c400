#include "specula/core/buffer.h"

#include <cstdlib>

#include "specula/core/huge_pages.h"

namespace specula::detail {

void* allocate_large(std::size_t bytes) {
  constexpr std::size_t kHugePage = std::size_t(1) << 21;
  if (bytes == 0 || bytes > std::numeric_limits<std::size_t>::max() - kHugePage) throw std::bad_alloc();
  const std::size_t size = (bytes + kHugePage - 1) / kHugePage * kHugePage;
  void* p = std::aligned_alloc(kHugePage, size);
  if (!p) throw std::bad_alloc();
  advise_huge_pages(p, size);
  return p;
}

void release_large(void* p) noexcept { std::free(p); }

}  // namespace specula::detail
