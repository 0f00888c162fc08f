// progiso/concurrent/append_log.hpp — an append-only array with stable addresses, written by one
// thread and read by any number, published by a watermark.
//
// What it is. Elements live in fixed chunks of 2^ChunkBits that never move; a directory of
// MaxChunks chunk pointers is reserved up front as a lazily zeroed mapping (it costs pages only
// as chunks are added). The writer appends with push_back() and makes a prefix visible with
// publish(); a reader calls published() once and may then read every element below the value it
// got, for as long as the log lives, while the writer keeps appending.
//
// When to use it: single-producer logs that readers walk by prefix (the engine's split records).
// Not for several writers, and not for elements that change after publication.
//
// Several writers: reserve() hands out n slots at the end (one writer at a time, like
// push_back(): under the writers' mutex); each reserving thread then fills its own slots through
// at_unpublished() without the mutex, and publish(n) makes a prefix visible once every slot
// below n is filled (the caller tracks that, and its hand-over to the publishing thread needs a
// happens-before of its own, e.g. the same mutex). The engine's full-refinement tasks copy their
// records outside the mutex this way (scheduler/src/full_refinement.cpp).
//
// Thread safety: push_back(), reserve(), publish(), size() and back() belong to one writer
// thread at a time (hand-overs between writers need their own happens-before, e.g. a serial
// flow-graph node or a mutex). at_unpublished(i) for a reserved, unpublished i belongs to the
// thread that reserved it. published() and operator[] below a published() value are safe from
// any thread. Construction and destruction are not concurrent with anything.
//
// Progress: every operation is wait-free; push_back() allocates a chunk every 2^ChunkBits
// elements (throws std::bad_alloc, or std::length_error past MaxChunks chunks, before anything
// changes).
//
// Memory ordering: publish() release-stores the watermark after the elements and the chunk
// pointers they live in were written; published() acquire-loads it, so a reader that sees n also
// sees elements [0, n) and their chunks. Elements at or past n are never read by readers, so
// the writer fills them without synchronisation.
#pragma once

#include <atomic>
#include <cstddef>
#include <memory>
#include <new>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include <progiso/core/base/assert.hpp>
#include <progiso/core/base/config.hpp>
#include <progiso/core/base/zeroed_array.hpp>

namespace progiso {

template <class T, std::size_t ChunkBits = 12, std::size_t MaxChunks = std::size_t{1} << 20>
class append_log {
  static_assert(std::is_trivially_copyable_v<T> && std::is_trivially_destructible_v<T>);

 public:
  static constexpr std::size_t chunk_size = std::size_t{1} << ChunkBits;
  static constexpr std::size_t max_chunks = MaxChunks;
  static constexpr std::size_t max_size = chunk_size * MaxChunks;

  append_log() : append_log(zeroed_array<T*>(MaxChunks)) {}
  /// A log on a chunk directory of MaxChunks null pointers: a fresh one, or one that another
  /// log handed back (release_directory()), so that the new log maps no memory (the directory
  /// is a mapping of 8 MiB, and mapping waits for the address space's lock, which threads
  /// faulting pages in hold, for long on a loaded machine; bench/README.md).
  explicit append_log(zeroed_array<T*>&& directory) : chunks_(std::move(directory)) {
    if (chunks_.size() != MaxChunks) {
      throw std::invalid_argument("append_log: a chunk directory of the wrong size");
    }
  }
  ~append_log() { free_chunks(); }
  append_log(const append_log&) = delete;
  append_log& operator=(const append_log&) = delete;

  /// Appends one element (not yet visible to readers). Writer only.
  void push_back(const T& value) {
    const std::size_t c = size_ >> ChunkBits;
    if ((size_ & (chunk_size - 1)) == 0) {
      if (c >= MaxChunks) throw std::length_error("append_log: capacity exceeded");
      chunks_[c] = new T[chunk_size];
    }
    chunks_[c][size_ & (chunk_size - 1)] = value;
    ++size_;
  }
  /// Reserves n slots at the end, allocating their chunks, and returns the first one's index;
  /// the slots hold garbage until the reserving thread fills them (at_unpublished()). Writer
  /// only. Throws as push_back() does, before anything changes.
  [[nodiscard]] std::size_t reserve(std::size_t n) {
    const std::size_t first = size_;
    if (n == 0) return first;
    const std::size_t last_chunk = (first + n - 1) >> ChunkBits;
    if (last_chunk >= MaxChunks) throw std::length_error("append_log: capacity exceeded");
    std::size_t c = (first + chunk_size - 1) >> ChunkBits;  // the first chunk not yet allocated
    try {
      for (; c <= last_chunk; ++c) chunks_[c] = new T[chunk_size];
    } catch (...) {
      for (std::size_t k = (first + chunk_size - 1) >> ChunkBits; k < c; ++k) {
        delete[] chunks_[k];
        chunks_[k] = nullptr;
      }
      throw;
    }
    size_ = first + n;
    return first;
  }
  /// Makes every element appended so far visible to readers. Writer only.
  void publish() noexcept { publish(size_); }
  /// Makes elements [0, n) visible to readers: n ≤ size(), never below an earlier publish, and
  /// every element below n filled and ordered before this call. Writer only.
  void publish(std::size_t n) noexcept {
    PROGISO_ASSERT(n <= size_ && n >= published_.load(std::memory_order_relaxed));
    // release: pairs with the acquire-load in published(); orders the elements and chunk
    // pointers written before it.
    published_.store(n, std::memory_order_release);
  }
  /// Elements appended (published or not). Writer only.
  [[nodiscard]] std::size_t size() const noexcept { return size_; }
  /// The visible prefix. Any thread.
  [[nodiscard]] std::size_t published() const noexcept {
    // acquire: pairs with the release-store in publish().
    return published_.load(std::memory_order_acquire);
  }
  /// Element i: by readers for i below a published() value they loaded, by the writer for any
  /// i < size().
  [[nodiscard]] const T& operator[](std::size_t i) const noexcept {
    return chunks_[i >> ChunkBits][i & (chunk_size - 1)];
  }
  /// Writer only: element i for in-place changes before publication.
  [[nodiscard]] T& at_unpublished(std::size_t i) noexcept {
    return chunks_[i >> ChunkBits][i & (chunk_size - 1)];
  }
  /// Frees the chunks and hands back the chunk directory, every entry null again, for a new log;
  /// this log is then empty and has no directory (destroy it). Only once no thread reads it.
  [[nodiscard]] zeroed_array<T*> release_directory() noexcept {
    free_chunks();
    size_ = 0;
    published_.store(0, std::memory_order_relaxed);  // relaxed: no reader is left
    return std::move(chunks_);
  }
  /// Bytes held by chunks (writer, or any thread once the writer is quiet).
  [[nodiscard]] std::size_t byte_size() const noexcept {
    return ((size_ + chunk_size - 1) >> ChunkBits) * chunk_size * sizeof(T);
  }

 private:
  void free_chunks() noexcept {
    for (std::size_t c = 0; c * chunk_size < size_; ++c) {
      delete[] chunks_[c];
      chunks_[c] = nullptr;
    }
  }

  zeroed_array<T*> chunks_;
  std::size_t size_ = 0;
  alignas(64) std::atomic<std::size_t> published_{0};
};

}  // namespace progiso
