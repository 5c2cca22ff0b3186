#pragma once
// Build buffers that give their memory back to the system when freed. The index build
// enumerates its triangles on worker threads; glibc keeps what their arenas free once its
// dynamic mmap threshold has grown (54 MB of a 1,000,000-tree mosaic's 281 MB resident were
// such garbage). Blocks from kMinMappedBytes up are pages mapped for them alone (mmap), smaller
// ones come from the heap.

#include <sys/mman.h>

#include <cstddef>
#include <new>
#include <vector>

namespace forestmap::algorithms {

inline constexpr size_t kMinMappedBytes = size_t{1} << 20;  // 1 MiB

template <typename T>
class PageAllocator {
 public:
  using value_type = T;
  PageAllocator() = default;
  template <typename U>
  PageAllocator(const PageAllocator<U>&) {}  // NOLINT: allocators convert implicitly

  T* allocate(size_t n) {
    const size_t bytes = n * sizeof(T);
    if (bytes < kMinMappedBytes) return static_cast<T*>(::operator new(bytes));
    void* p = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    return static_cast<T*>(p);
  }
  void deallocate(T* p, size_t n) {
    const size_t bytes = n * sizeof(T);
    if (bytes < kMinMappedBytes) {
      ::operator delete(p);
    } else {
      munmap(p, bytes);
    }
  }
  template <typename U>
  bool operator==(const PageAllocator<U>&) const {
    return true;
  }
};

template <typename T>
using PageVector = std::vector<T, PageAllocator<T>>;

}  // namespace forestmap::algorithms
