// progiso/core/detail/zeroed_array.hpp — a large zero-filled array whose pages cost nothing until
// touched.
//
// The refiners keep a few bytes per grid vertex but touch only the vertices near the surface.
// calloc() zero-fills eagerly once glibc has raised its mmap threshold (it does after large frees),
// which costs milliseconds for a 257³ grid and would spoil the time to first surface; an
// anonymous mapping is zeroed lazily by the kernel, page by page, on first touch. Not
// thread-safe to create or destroy; elements follow T's own rules.
#pragma once

#include <sys/mman.h>

#include <cstddef>
#include <new>
#include <type_traits>

namespace progiso::detail {

template <class T>
class zeroed_array {
  static_assert(std::is_trivially_copyable_v<T> && std::is_trivially_destructible_v<T>);

 public:
  explicit zeroed_array(std::size_t n) : bytes_(n * sizeof(T)) {
    if (bytes_ == 0) return;
    void* p = mmap(nullptr, bytes_, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    data_ = static_cast<T*>(p);
  }
  zeroed_array(const zeroed_array&) = delete;
  zeroed_array& operator=(const zeroed_array&) = delete;
  ~zeroed_array() {
    if (data_ != nullptr) munmap(data_, bytes_);
  }

  [[nodiscard]] T* get() const noexcept { return data_; }
  T& operator[](std::size_t i) const noexcept { return data_[i]; }

 private:
  std::size_t bytes_;
  T* data_ = nullptr;
};

}  // namespace progiso::detail
