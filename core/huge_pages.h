#pragma once
// Advice to the kernel that memory be backed by 2 MB pages (Linux's transparent huge pages in `madvise` mode):
// a first touch then costs one fault per 2 MB instead of one per 4 KB.

#include <cstddef>

namespace specula {

/// The size of a huge page (x86-64's 2 MB transparent huge pages).
inline constexpr std::size_t kHugePageBytes = std::size_t(1) << 21;

/// The huge pages lying wholly within [p, p + bytes) advised as huge pages; advice only (nothing where the system
/// has no huge pages, and memory already touched keeps its pages).
void advise_huge_pages(void* p, std::size_t bytes) noexcept;

}  // namespace specula
