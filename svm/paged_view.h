// PagedView: the database view of svm mode (docs/architecture.md, "One tracer,
// several data views"). Every object the one tracer reads — a cell's
// directory entry, the pieces of its primitive list, a primitive, a
// triangle's vertex normals — is found through the node's page table
// (pager.h) at the place the host's layout put it (paged_database.h); a
// page that is not resident is a page fault. Materials and the grid's O(1)
// description are replicated on the node.
//
// An object is read at its shared-virtual-memory address (Pager::at): its
// segment's first address plus its place in the segment (a cell's 4-byte
// directory entry, a primitive's 64-byte record, the byte address of a
// list or of a packed cell's run that the directory entry holds), so that
// the pager finds page and byte with one shift and one add.
//
// Because the bytes are the host's records, copied page by page, and the
// traversal and shading code are the same, images are bit-identical to
// sequential mode.
//
// Reference lifetime: primitive() and vertex_normals() return references
// into a frame that the next access may evict (a one-page cache does so
// every time); the tracer uses them before its next view call
// (core/traverse.h). for_each_in_cell visits a copy of a list piece that
// lies in a cache frame (f() may evict it); home pages never move. A packed
// cell's blocks (--pack-cells) are handed to visit_cell's `packed` one page
// piece at a time; `packed` reads only them, so its frame stays put.
//
// The directory's entries lie in the linear cell order or in bricks
// (DirectoryOrder); BrickedPagedView makes the walk keep bricked keys.
// For an adaptive grid the top grid is walked in that order; a cell
// holding a sub-grid has the entry kSubGridCode + i, which visit_cell
// returns as it returns an empty cell's distance, and the walk
// (core/traverse.h, has_paged_sub_grids) reads sub-grid i's record
// through sub_grid(i) and walks its cells by their directory keys.
//
// Thread safety: owner node thread only.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <span>
#include <stdexcept>

#include <fmt/core.h>

#include "core/cell_blocks.h"
#include "core/database.h"
#include "core/grid.h"
#include "core/render.h"
#include "svm/pager.h"

namespace raynode::svm {

class PagedView {
 public:
  /// `materials` live in the node's arena (replicated metadata).
  /// For a directory in the linear order; throws std::logic_error for a
  /// bricked one (BrickedPagedView walks those).
  PagedView(Pager& pager, const core::TopGridInfo& grid, std::span<const core::Material> materials)
      : PagedView(pager, grid, materials, DirectoryOrder::kLinear) {}

  const core::TopGridInfo& grid_info() const { return grid_; }
  /// True for an adaptive grid's layout (sub-grid records are paged).
  bool has_sub_grids() const { return layout_.sub_grids > 0; }
  /// The directory key of the leaf listing the scene's large primitives
  /// beside the top grid, or core::kNoLeaf (replicated: no page access).
  std::uint32_t top_large_leaf() const { return layout_.top_large_key; }
  /// A copy of sub-grid record i (< layout's sub_grids): its grid and the
  /// directory key of its cell 0 as first_entry. One page access.
  core::SubGrid sub_grid(std::uint32_t i) const {
    PagedSubGrid r;
    std::memcpy(&r, pager_->at(layout_.sub_grid_address(i)), sizeof r);
    return core::SubGrid{r.info, r.first_key & ~kLargeListKey, 0, (r.first_key & kLargeListKey) != 0};
  }
  /// visit_cell's and for_each_in_cell's `cell` is the cell's directory
  /// key: its index in the linear order, its bricked key in the other.

  /// Calls f(id) for each primitive the cell lists (a packed cell: each
  /// triangle of its blocks, in list order); returns the empty cell's
  /// empty-space distance, or 0.
  template <class F>
  std::uint32_t for_each_in_cell(std::uint32_t cell, F&& f) const {
    return visit_cell(cell, f, [&](const core::CellBlockSpan& cb) {
      // f() may evict the piece's frame: its ids first (8 per 320-byte
      // block, so they fit in the page-sized list buffer).
      std::uint32_t* ids = pager_->list_buffer();
      std::uint32_t n = 0;
      for (std::uint32_t k = 0, left = cb.triangles; k < cb.block_count; ++k, left -= core::kBlockLanes)
        for (std::uint32_t l = 0; l < std::min(left, core::kBlockLanes); ++l) ids[n++] = cb.blocks[k].primitive[l];
      for (std::uint32_t i = 0; i < n; ++i) f(ids[i]);
    });
  }
  /// for_each_in_cell, except that a packed cell's blocks are handed to
  /// packed(const core::CellBlockSpan&), a page's piece at a time.
  template <class F, class P>
  std::uint32_t visit_cell(std::uint32_t cell, F&& f, P&& packed) const {
    // The directory is the first segment: a cell's entry lies at cell x 4.
    DirectoryEntry e;
    std::memcpy(&e, pager_->at(std::uint64_t(cell) * sizeof(DirectoryEntry)), sizeof e);
    if (e < kSingleCell) return e;  // an empty cell: the entry is its empty-space distance
    if (e < kListCell) {
      if (e < kPackedCell) {
        f(e - kSingleCell);  // a cell's one primitive
        return 0;
      }
      // A packed cell: its run's header (the triangle count), then its blocks.
      const std::uint32_t header = e - kPackedCell;
      const std::byte* head = pager_->at(blocks_ + header);
      std::uint32_t triangles;
      std::memcpy(&triangles, head, sizeof triangles);
      const std::uint32_t blocks = (triangles + core::kBlockLanes - 1) / core::kBlockLanes;
      const std::uint32_t in_page = layout_.page_size - (header & (layout_.page_size - 1)) - kPackedHeaderBytes;
      if (blocks * std::uint32_t(sizeof(core::TriangleBlock)) <= in_page) [[likely]]
        packed(core::CellBlockSpan{reinterpret_cast<const core::TriangleBlock*>(head + kPackedHeaderBytes), blocks,
                                   triangles});
      else
        visit_chained_blocks(blocks_ + header + kPackedHeaderBytes, blocks, triangles, packed);
      return 0;
    }
    // A list. The tag lies in bits 30-31, above any page offset, so
    // e & (page_size - 1) is still the header's byte in its page.
    const std::uint64_t list = lists_ + (e - kListCell);
    const std::byte* head = pager_->at(list);  // the list's header (its count), then its ids
    std::uint32_t count;
    std::memcpy(&count, head, sizeof count);
    // The ids follow the header; a list longer than the rest of its page
    // goes on at the next page's first byte.
    std::uint32_t left = count;
    std::uint32_t n = std::min(left, (layout_.page_size - (e & (layout_.page_size - 1)) - 4) / 4);
    const std::uint32_t* ids = reinterpret_cast<const std::uint32_t*>(head + 4);
    std::uint64_t address = list + 4;
    for (;;) {
      if (pager_->in_cache(ids)) [[unlikely]] {
        // f() may evict this cache page (a one-page cache does): visit a copy.
        std::uint32_t* copy = pager_->list_buffer();
        std::memcpy(copy, ids, n * sizeof(std::uint32_t));
        ids = copy;
      }
      for (std::uint32_t i = 0; i < n; ++i) f(ids[i]);
      left -= n;
      if (left == 0) return 0;
      address += n * sizeof(std::uint32_t);  // the next page's first id
      n = std::min(left, layout_.page_size / std::uint32_t(sizeof(std::uint32_t)));
      ids = reinterpret_cast<const std::uint32_t*>(pager_->at(address));
    }
  }
  const core::Primitive& primitive(std::uint32_t id) const {
    return *reinterpret_cast<const core::Primitive*>(pager_->at(primitives_ + std::uint64_t(id) * sizeof(core::Primitive)));
  }
  const core::Material& material(std::uint32_t id) const { return materials_[id]; }
  const core::TriangleNormals& vertex_normals(std::uint32_t id) const {
    return *reinterpret_cast<const core::TriangleNormals*>(pager_->access(layout_.normals_page(id)) +
                                                           layout_.normals_offset(id));
  }

 protected:
  PagedView(Pager& pager, const core::TopGridInfo& grid, std::span<const core::Material> materials, DirectoryOrder order)
      : pager_(&pager),
        layout_(pager.layout()),
        lists_(layout_.address(layout_.list_first)),
        primitives_(layout_.address(layout_.primitive_first)),
        blocks_(layout_.address(layout_.block_first)),
        grid_(grid),
        materials_(materials) {
    if (layout_.directory_first != 0)
      throw std::logic_error(fmt::format("svm: the cell directory starts at page {}, not at address 0",
                                         layout_.directory_first));
    if (layout_.directory_order != order)
      throw std::logic_error(fmt::format("svm: a view for a {} cell directory over a {} one",
                                         directory_order_name(order), directory_order_name(layout_.directory_order)));
  }

 private:
  /// A packed cell whose blocks continue page after page: a piece per page.
  template <class P>
  void visit_chained_blocks(std::uint64_t address, std::uint32_t blocks, std::uint32_t triangles, P& packed) const {
    while (blocks > 0) {
      const std::uint32_t room =
          (layout_.page_size - std::uint32_t(address & (layout_.page_size - 1))) / std::uint32_t(sizeof(core::TriangleBlock));
      const std::uint32_t n = std::min(blocks, room);
      const std::uint32_t in_piece = std::min(triangles, n * core::kBlockLanes);
      packed(core::CellBlockSpan{reinterpret_cast<const core::TriangleBlock*>(pager_->at(address)), n, in_piece});
      blocks -= n;
      triangles -= in_piece;
      address = (address | (layout_.page_size - 1)) + 1;  // the next page's first block
    }
  }

  Pager* pager_;
  PageLayout layout_;  // a copy: its fields stay in the view, one load away
  /// The segments' first addresses in the shared virtual memory.
  std::uint64_t lists_, primitives_, blocks_;
  core::TopGridInfo grid_;
  std::span<const core::Material> materials_;
};

/// PagedView over a bricked cell directory: the walk numbers the cells by
/// their bricked keys (core/cell_order.h), read from `order`, tables built
/// for the layout's bricks and the grid (which outlive the view).
class BrickedPagedView : public PagedView {
 public:
  BrickedPagedView(Pager& pager, const core::TopGridInfo& grid, std::span<const core::Material> materials,
                   const core::CellKeyTables& order)
      : PagedView(pager, grid, materials, DirectoryOrder::kBricked), order_(order) {}
  const core::CellKeyTables& cell_order() const { return order_; }

 private:
  core::CellKeyTables order_;  // a copy: six pointers, one load away
};

}  // namespace raynode::svm

namespace raynode::core {
// The tracer over both views is compiled once, in paged_view.cpp and
// paged_view_bricked.cpp.
RAYNODE_PIXEL_INSTANCES(extern, svm::PagedView);
RAYNODE_PIXEL_INSTANCES(extern, svm::BrickedPagedView);
}  // namespace raynode::core
