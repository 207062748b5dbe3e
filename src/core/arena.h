// Workspace memory that can come from one block the caller owns (docs/flight.md, "Memory").
//
// The stages' workspaces (detect, identify, the fusion's rings) keep their buffers in ScratchVec and
// take a std::pmr::memory_resource at construction: the heap by default (ground tools, Python), an
// Arena over the caller's block in the flight core, whose handle then takes nothing from the heap for
// them. An Arena made with Arena::Meter() measures what such a block needs: the heap serves each
// request while used() counts the block's bytes, alignment included.
#pragma once
#include <cstddef>
#include <cstdint>
#include <memory>
#include <memory_resource>
#include <new>
#include <utility>
#include <vector>

namespace ssiu {

template <class T>
using ScratchVec = std::pmr::vector<T>;

// Bump allocation in [block, block + bytes): nothing is handed back until the arena goes, so the
// block's use is the sum of its requests, each aligned (JPL Power of Ten rule 3: memory is taken at
// initialisation only). Past the end: std::bad_alloc, which the flight core's init turns into
// SSIU_ERR_MEMORY. The block must be aligned to kBlockAlign.
class Arena final : public std::pmr::memory_resource {
 public:
  static constexpr size_t kBlockAlign = 16;
  Arena(void* block, size_t bytes) : block_(static_cast<unsigned char*>(block)), size_(bytes) {}
  // Measures instead: every request is served by the heap (and given back to it), used() grows as the
  // block's would.
  static Arena Meter() { return Arena(nullptr, 0); }
  Arena(const Arena&) = delete;
  Arena& operator=(const Arena&) = delete;

  size_t used() const { return used_; }
  bool measuring() const { return block_ == nullptr; }

 private:
  void* do_allocate(size_t bytes, size_t align) override {
    // Offsets are aligned within the block (itself kBlockAlign-aligned); a larger alignment is met on
    // the address, for which the meter counts the worst case.
    size_t start = (used_ + align - 1) & ~(align - 1);
    if (measuring()) {
      if (align > kBlockAlign) start += align - kBlockAlign;
      used_ = start + bytes;
      return ::operator new(bytes, std::align_val_t(align));
    }
    if (align > kBlockAlign) {
      const uintptr_t a = reinterpret_cast<uintptr_t>(block_) + used_;
      start = used_ + (((a + align - 1) & ~(uintptr_t{align} - 1)) - a);
    }
    if (start > size_ || bytes > size_ - start) throw std::bad_alloc();
    used_ = start + bytes;
    return block_ + start;
  }
  void do_deallocate(void* p, size_t /*bytes*/, size_t align) override {
    if (measuring()) ::operator delete(p, std::align_val_t(align));
  }
  bool do_is_equal(const std::pmr::memory_resource& o) const noexcept override { return this == &o; }

  unsigned char* block_;
  size_t size_;
  size_t used_ = 0;
};

// Makes *v (a member made before its owner knew its resource) an empty vector in `mr`: for
// construction time only, whatever it held is dropped.
template <class T>
void UseResource(ScratchVec<T>* v, std::pmr::memory_resource* mr) {
  if (v->get_allocator().resource() == mr) return;
  std::destroy_at(v);
  ::new (static_cast<void*>(v)) ScratchVec<T>(mr);
}

// One object in a memory resource, destroyed and given back by its unique_ptr.
template <class T>
struct ResourceDelete {
  std::pmr::memory_resource* mr = nullptr;
  void operator()(T* p) const {
    p->~T();
    mr->deallocate(p, sizeof(T), alignof(T));
  }
};
template <class T>
using ResourcePtr = std::unique_ptr<T, ResourceDelete<T>>;

template <class T, class... Args>
ResourcePtr<T> MakeInResource(std::pmr::memory_resource* mr, Args&&... args) {
  void* p = mr->allocate(sizeof(T), alignof(T));
  try {
    return ResourcePtr<T>(new (p) T(std::forward<Args>(args)...), ResourceDelete<T>{mr});
  } catch (...) {
    mr->deallocate(p, sizeof(T), alignof(T));
    throw;
  }
}

}  // namespace ssiu
