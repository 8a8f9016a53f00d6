// A node's private memory: a byte budget that everything the node holds is
// allocated from (docs/architecture.md, "The node emulator"; the paper's iPSC/2 node has
// 4 MiB). Place in the data flow: Machine creates one Arena per node (and an
// unbounded one for the host); the node's mailbox, its share of the database,
// its page cache and page table are all carved from it.
//
// The arena is an accounting memory resource: every request is charged at
// its exact byte count against the budget, and a request that would exceed
// it throws ArenaExhausted naming the node, the request, what is in use and
// the budget — it never falls back silently to the global heap. Memory given
// back is credited again. The bytes themselves come from the upstream
// operator new, so the budget is exact to the byte while the arena stays
// free of fragmentation policy (what a real node's malloc would add is not
// modelled).
//
// Thread safety: owner thread only (the host may fill a node's arena before
// the node's thread starts).
#pragma once

#include <cstddef>
#include <cstring>
#include <cstdint>
#include <memory_resource>
#include <new>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

namespace raynode::nodes {

/// Node ids: 0 .. nodes-1 are the nodes; kHost is the host.
using NodeId = std::uint32_t;
inline constexpr NodeId kHost = 0xffffffffu;

/// "node 3" or "host".
std::string node_name(NodeId id);

/// Something does not fit a node's memory: a mode's check before a run
/// (svm's database or cache, a dataflow region, replicated's copy) or an
/// allocation during one (ArenaExhausted). Carries the bytes needed and the
/// node's budget; what() names them. Experiment commands record such a run
/// as skipped; render exits 1 with the message.
class DoesNotFit : public std::runtime_error {
 public:
  DoesNotFit(const std::string& message, std::size_t needed, std::size_t budget)
      : std::runtime_error(message), needed(needed), budget(budget) {}
  std::size_t needed, budget;  ///< bytes
};

/// Thrown when an allocation would exceed a node's memory budget.
class ArenaExhausted : public DoesNotFit {
 public:
  ArenaExhausted(NodeId node, std::size_t requested, std::size_t in_use, std::size_t budget, const std::string& what);
  NodeId node;
  std::size_t requested, in_use, budget;
};

/// Formats a byte count for messages: "4 MiB", "1.5 KiB", "733 B".
std::string format_bytes(std::size_t bytes);

/// Tag: an arena array whose elements are left uninitialised.
struct Uninitialized {};
inline constexpr Uninitialized kUninitialized{};

/// A node's memory budget. See the file comment.
class Arena : public std::pmr::memory_resource {
 public:
  /// Budget in bytes; `node` names the owner in errors.
  Arena(NodeId node, std::size_t budget_bytes);
  Arena(const Arena&) = delete;
  Arena& operator=(const Arena&) = delete;
  ~Arena() override = default;

  NodeId node() const { return node_; }
  std::size_t budget() const { return budget_; }
  std::size_t used() const { return used_; }
  std::size_t peak() const { return peak_; }
  std::size_t available() const { return budget_ - used_; }
  std::uint64_t allocations() const { return allocations_; }

  /// Raw bytes charged to the budget; `what` names the purpose in errors.
  /// Throws ArenaExhausted. The memory is uninitialised.
  void* allocate_bytes(std::size_t bytes, std::size_t align, const char* what);
  void deallocate_bytes(void* p, std::size_t bytes, std::size_t align) noexcept;

  /// n value-initialised T's (T trivially destructible); throws ArenaExhausted.
  template <class T>
  std::span<T> allocate_array(std::size_t n, const char* what) {
    const std::span<T> a = allocate_raw_array<T>(n, what);
    for (std::size_t i = 0; i < n; ++i) new (a.data() + i) T();
    return a;
  }
  /// n T's left uninitialised (T trivially copyable, so that bytes copied
  /// in make its objects): for arrays that are written before they are
  /// read (a copy of the host's data, a page cache), so that nothing
  /// touches, and the operating system need not back, memory the render
  /// never uses. Throws ArenaExhausted.
  template <class T>
  std::span<T> allocate_uninitialized_array(std::size_t n, const char* what) {
    static_assert(std::is_trivially_copyable_v<T>, "an uninitialised arena array holds plain records");
    return allocate_raw_array<T>(n, what);
  }
  template <class T>
  void deallocate_array(std::span<T> a) noexcept {
    deallocate_bytes(a.data(), a.size() * sizeof(T), alignof(T));
  }

  /// One T constructed in the arena; pair with destroy(). Throws ArenaExhausted.
  template <class T, class... Args>
  T* create(const char* what, Args&&... args) {
    void* p = allocate_bytes(sizeof(T), alignof(T), what);
    try {
      return new (p) T(std::forward<Args>(args)...);
    } catch (...) {
      deallocate_bytes(p, sizeof(T), alignof(T));
      throw;
    }
  }
  template <class T>
  void destroy(T* p) noexcept {
    if (!p) return;
    p->~T();
    deallocate_bytes(p, sizeof(T), alignof(T));
  }

 private:
  template <class T>
  std::span<T> allocate_raw_array(std::size_t n, const char* what) {
    static_assert(std::is_trivially_destructible_v<T>, "arena arrays hold plain records");
    if (n > budget_ / sizeof(T)) throw_exhausted(n > SIZE_MAX / sizeof(T) ? SIZE_MAX : n * sizeof(T), what);
    return {static_cast<T*>(allocate_bytes(n * sizeof(T), alignof(T), what)), n};
  }
  void* do_allocate(std::size_t bytes, std::size_t align) override;
  void do_deallocate(void* p, std::size_t bytes, std::size_t align) override;
  bool do_is_equal(const std::pmr::memory_resource& other) const noexcept override { return this == &other; }
  [[noreturn]] void throw_exhausted(std::size_t bytes, const char* what) const;

  NodeId node_;
  std::size_t budget_;
  std::size_t used_ = 0;
  std::size_t peak_ = 0;
  std::uint64_t allocations_ = 0;
};

/// An array owned by an arena, freed back to it on destruction (move-only).
template <class T>
class ArenaArray {
 public:
  ArenaArray() = default;
  ArenaArray(Arena& arena, std::size_t n, const char* what) : arena_(&arena), data_(arena.allocate_array<T>(n, what)) {}
  /// n T's left uninitialised (Arena::allocate_uninitialized_array).
  ArenaArray(Arena& arena, std::size_t n, const char* what, Uninitialized)
      : arena_(&arena), data_(arena.allocate_uninitialized_array<T>(n, what)) {}
  ArenaArray(ArenaArray&& o) noexcept : arena_(o.arena_), data_(o.data_) { o.data_ = {}; }
  ArenaArray& operator=(ArenaArray&& o) noexcept {
    if (this != &o) {
      release();
      arena_ = o.arena_;
      data_ = o.data_;
      o.data_ = {};
    }
    return *this;
  }
  ~ArenaArray() { release(); }

  std::span<T> span() const { return data_; }
  T* data() const { return data_.data(); }
  std::size_t size() const { return data_.size(); }
  T& operator[](std::size_t i) const { return data_[i]; }

 private:
  void release() {
    if (arena_ && data_.data()) arena_->deallocate_array(data_);
    data_ = {};
  }
  Arena* arena_ = nullptr;
  std::span<T> data_;
};

/// A copy of `src` in a new array of `arena` (T trivially copyable): how the
/// host loads a node's memory. Throws ArenaExhausted naming `what`.
template <class T>
ArenaArray<T> copy_to_arena(Arena& arena, std::span<const T> src, const char* what) {
  ArenaArray<T> a(arena, src.size(), what, kUninitialized);  // asserts T trivially copyable
  if (!src.empty()) std::memcpy(static_cast<void*>(a.data()), src.data(), src.size_bytes());
  return a;
}

}  // namespace raynode::nodes
