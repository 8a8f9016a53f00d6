#include "nodes/arena.h"

#include <fmt/core.h>

#include <algorithm>

namespace raynode::nodes {

std::string node_name(NodeId id) { return id == kHost ? std::string("host") : fmt::format("node {}", id); }

std::string format_bytes(std::size_t bytes) {
  const double b = double(bytes);
  if (bytes >= (std::size_t(1) << 30)) return fmt::format("{:.4g} GiB", b / double(1 << 30));
  if (bytes >= (std::size_t(1) << 20)) return fmt::format("{:.4g} MiB", b / double(1 << 20));
  if (bytes >= (std::size_t(1) << 10)) return fmt::format("{:.4g} KiB", b / double(1 << 10));
  return fmt::format("{} B", bytes);
}

ArenaExhausted::ArenaExhausted(NodeId node, std::size_t requested, std::size_t in_use, std::size_t budget,
                               const std::string& what)
    : DoesNotFit(fmt::format("{}: out of node memory: {} needs {} ({} B) but {} of the {} budget ({} B) "
                             "is in use, {} B free",
                             node_name(node), what, format_bytes(requested), requested, format_bytes(in_use),
                             format_bytes(budget), budget, budget - in_use),
                 in_use + requested, budget),
      node(node),
      requested(requested),
      in_use(in_use),
      budget(budget) {}

Arena::Arena(NodeId node, std::size_t budget_bytes) : node_(node), budget_(budget_bytes) {}

void Arena::throw_exhausted(std::size_t bytes, const char* what) const {
  throw ArenaExhausted(node_, bytes, used_, budget_, what ? what : "an allocation");
}

void* Arena::allocate_bytes(std::size_t bytes, std::size_t align, const char* what) {
  if (bytes > budget_ - used_) throw_exhausted(bytes, what);
  void* p = ::operator new(std::max<std::size_t>(bytes, 1), std::align_val_t(std::max(align, alignof(std::max_align_t))));
  used_ += bytes;
  peak_ = std::max(peak_, used_);
  ++allocations_;
  return p;
}

void Arena::deallocate_bytes(void* p, std::size_t bytes, std::size_t align) noexcept {
  if (!p) return;
  ::operator delete(p, std::align_val_t(std::max(align, alignof(std::max_align_t))));
  used_ -= std::min(bytes, used_);
}

void* Arena::do_allocate(std::size_t bytes, std::size_t align) { return allocate_bytes(bytes, align, "an allocation"); }

void Arena::do_deallocate(void* p, std::size_t bytes, std::size_t align) { deallocate_bytes(p, bytes, align); }

}  // namespace raynode::nodes
