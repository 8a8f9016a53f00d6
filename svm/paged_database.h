// The shared virtual memory's contents: the whole tracing database laid out
// in fixed-size pages by the host (paper, "Distributing data": object
// paging, "an object belongs to one and only one page"; docs/architecture.md, "svm").
//
// Place in the data flow: Database + Grid (host) -> build_paged_image ->
// PagedImage (PageLayout + every page's bytes) -> each node's setup copies
// its home pages (page p lives on node p mod N: dealt evenly, round robin,
// no locality strategy) -> the image is protected and freed; nodes reach
// objects only through their pager (pager.h) and PagedView (paged_view.h).
//
// Segments, in page order (each starts on a page boundary; the directory
// is first, at address 0, which PagedView relies on):
//   directory  one 4-byte DirectoryEntry per grid cell (the "voxels"),
//              in cell order or, bricked, a page per brick of cells
//              (DirectoryOrder, core/cell_order.h; a brick's unused
//              slots and the grid's edge bricks' padding stay zero):
//              an empty cell's empty-space distance (so that the walk's
//              jumps need no other replicated or paged data), the one
//              primitive id of an unpacked cell that lists one, or else
//              the byte address of the cell's list, or of a packed cell's
//              run of blocks. For an adaptive grid (core/grid.h) these are
//              the top grid's cells; the sub-grids' cells follow, each
//              sub-grid's in its linear order, sub-grids in build order,
//              and a cell that holds sub-grid i has the entry
//              kSubGridCode + i (an "empty" tag above every distance);
//   sub-grids  adaptive only: one 64-byte PagedSubGrid record per grid of
//              the hierarchy (index 0 the top grid), page_size/64 per page;
//   lists      for each unpacked cell that lists two primitives or more, a
//              header word (how many) followed by the primitive ids (4
//              bytes each), cells in the directory's key order (so that
//              a bricked directory page's cells have their lists
//              together). A list that does not fit
//              in the rest of the current page but fits in one page starts
//              on a fresh page, a longer list continues page after page (a
//              chain of per-page pieces, each an object in one page; the
//              header is in the first);
//   primitives the 64-byte Primitive records, page_size/64 per page, in
//              file order (the database's, the paper's) or in cell order
//              (PrimitiveOrder): slot by slot as the cells, walked in
//              directory key order, first list them, so that the few
//              primitives a cell lists share a page with its neighbours'
//              instead of lying wherever the file put them. Then the
//              directory's one-primitive entries, the lists and the
//              packed blocks hold slots; a slot's record is the
//              primitive's, so a hit shades, and an image comes out, the
//              same in either order;
//   normals    the 36-byte TriangleNormals of `pp` triangles,
//              floor(page_size/36) per page (in cell order: in the order
//              of their triangles' slots);
//   blocks     only with --pack-cells N (off by default, as in the paper):
//              each packed cell's run, a 32-byte header (its triangle
//              count, then zeros) and its 320-byte core::TriangleBlocks
//              (core/cell_blocks.h), cells in the directory's key
//              order; a run that fits
//              in the rest of the current page goes there, any other
//              starts on a fresh page, and one longer than a page goes on
//              at the next page's first byte with as many whole blocks as
//              each page holds (PageLayout::packed_block_address). The
//              tracer tests them a block at a time (same hits); the header
//              lies in the page of the cell's first blocks, so one page
//              access finds count and blocks.
// Only O(1) metadata is replicated on every node instead: GridInfo,
// materials, lights, camera, background, and this layout.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "core/cell_blocks.h"
#include "core/cell_order.h"
#include "core/database.h"
#include "core/grid.h"

namespace raynode::svm {

/// One grid cell's entry in the paged cell directory, a 32-bit word whose
/// top two bits (its tag, kEntryTag) say what the other 30 (its value) are:
///   kEmptyCell | d    an empty cell; d = its empty-space distance
///                     (core::Grid::empty_distance), so that the entry
///                     *is* the distance;
///   kSingleCell | id  an unpacked cell that lists one primitive, its id;
///   kPackedCell | a   a packed cell; a = the byte address of its run's
///                     header in the blocks segment;
///   kListCell | a     a cell with a list; a = the byte address of its
///                     list header in the lists segment.
/// Four bytes, not a count and an address, put twice the cells in a
/// directory page: the directory is the database's most shared segment
/// (every ray that crosses the grid reads it), and a node fetches pages of
/// it wherever its rays go. A one-primitive cell needs no list access.
/// Empty cells, most of the cells a ray visits, have the tag 0: the view's
/// first compare (entry < kSingleCell) finds one, and the entry is the
/// distance it returns.
using DirectoryEntry = std::uint32_t;
inline constexpr std::uint32_t kEmptyCell = 0;
inline constexpr std::uint32_t kSingleCell = 1u << 30;
inline constexpr std::uint32_t kPackedCell = 2u << 30;
inline constexpr std::uint32_t kListCell = 3u << 30;
/// The tag bits of a DirectoryEntry.
inline constexpr std::uint32_t kEntryTag = 3u << 30;
/// Largest list or run address and primitive id an entry can hold.
inline constexpr std::uint32_t kMaxEntryValue = kSingleCell - 1;
/// Bytes of a packed cell's run header (keeps its blocks 32-byte aligned).
inline constexpr std::uint32_t kPackedHeaderBytes = 32;

/// The order of the cell directory's entries (core/cell_order.h): linear
/// (cell order, the paper's) or bricked (a page per brick of cells, so a
/// ray meets a new directory page every few cells on any axis).
enum class DirectoryOrder : std::uint8_t { kLinear, kBricked };
/// "linear", "bricked".
const char* directory_order_name(DirectoryOrder o);
/// "linear", "bricked" or "auto" (nullopt: the mode chooses); throws
/// std::invalid_argument naming the text otherwise.
std::optional<DirectoryOrder> parse_directory_order(const std::string& text);

/// The order of the records in the primitives segment (file comment):
/// the database's (file) or the cells' (cell).
enum class PrimitiveOrder : std::uint8_t { kFile, kCell };
/// "file", "cell".
const char* primitive_order_name(PrimitiveOrder o);
/// "file", "cell" or "auto" (nullopt: the mode chooses); throws
/// std::invalid_argument naming the text otherwise.
std::optional<PrimitiveOrder> parse_primitive_order(const std::string& text);

/// The segments of the shared virtual memory (in page order: directory,
/// sub-grids, lists, primitives, normals, blocks).
enum class Segment : std::uint8_t { kDirectory, kLists, kPrimitives, kNormals, kBlocks, kSubGrids };
inline constexpr std::size_t kSegments = 6;
/// "directory", "lists", "primitives", "normals", "blocks", "sub-grids".
const char* segment_name(Segment s);

/// One grid of an adaptive hierarchy as svm pages it: the walk's
/// description of it and the directory key of its cell 0 (its cells'
/// entries follow in its linear cell order). 64 bytes, so a record never
/// straddles a page.
struct PagedSubGrid {
  core::GridInfo info;
  /// The directory key of its cell 0, | kLargeListKey when the key after
  /// its cells lists the parent cell's large primitives (core::SubGrid).
  std::uint32_t first_key = 0;
};
/// PagedSubGrid::first_key's flag bit (directory keys fit 31 bits).
inline constexpr std::uint32_t kLargeListKey = 0x80000000u;
static_assert(sizeof(PagedSubGrid) == 64, "a sub-grid record is a power of two not above the smallest page");

/// Smallest page: one Primitive record.
inline constexpr std::uint32_t kMinPageSize = sizeof(core::Primitive);
/// Largest page (a page travels in one message).
inline constexpr std::uint32_t kMaxPageSize = 1u << 20;

/// Where every object lies: page numbers and offsets, for the host's
/// builder and every node's view. Plain data, replicated on every node.
struct PageLayout {
  std::uint32_t page_size = 1024;  ///< bytes, a power of two in [kMinPageSize, kMaxPageSize]
  std::uint32_t page_shift = 10;   ///< log2(page_size)
  std::uint32_t pages = 0;         ///< pages in the shared virtual memory

  std::uint32_t directory_first = 0, directory_pages = 0;
  std::uint32_t sub_grid_first = 0, sub_grid_pages = 0;
  std::uint32_t list_first = 0, list_pages = 0;
  std::uint32_t primitive_first = 0, primitive_pages = 0;
  std::uint32_t normals_first = 0, normals_pages = 0;
  std::uint32_t block_first = 0, block_pages = 0;

  std::uint32_t directory_shift = 0;   ///< log2(directory entries per page)
  DirectoryOrder directory_order = DirectoryOrder::kLinear;
  /// Bricked order: the brick shape (its slots = directory entries per
  /// page). A cell's entry is at its key (core::CellBricks::key); in the
  /// linear order the key is the cell's index.
  core::CellBricks bricks;
  PrimitiveOrder primitive_order = PrimitiveOrder::kFile;
  std::uint32_t primitive_shift = 0;   ///< log2(primitives per page)
  std::uint32_t normals_per_page = 0;  ///< TriangleNormals per page
  std::uint32_t blocks_per_page = 0;   ///< TriangleBlocks per page (a long run's pages after its first)

  /// Directory entries in use: the grid's cells (adaptive: of every grid
  /// of the hierarchy); the top grid's are the first top_cells.
  std::uint32_t cells = 0, primitives = 0, normal_sets = 0;
  std::uint32_t top_cells = 0;  ///< cells of the (top) grid
  /// Directory keys of the top grid (its cells, or its bricks' slots): a
  /// sub-grid cell's entry e (>= top_cells) has key top_keys + e - top_cells.
  std::uint32_t top_keys = 0;
  std::uint32_t sub_grids = 0;  ///< PagedSubGrid records (0: a uniform grid)
  /// The directory key of the leaf listing the scene's large primitives
  /// beside the top grid (core::SubGrid::large_list of the top grid), or
  /// core::kNoLeaf.
  std::uint32_t top_large_key = core::kNoLeaf;
  std::uint32_t listed_cells = 0;  ///< unpacked cells with a list (two primitives or more)
  std::uint32_t single_cells = 0;  ///< cells whose one primitive is in the directory entry
  std::uint32_t list_ids = 0;      ///< primitive ids in the lists segment
  std::uint32_t pack_min = 0;       ///< least triangles of a packed cell; 0 = no packed cell
  std::uint32_t packed_cells = 0, blocks = 0;
  std::uint64_t object_bytes = 0;  ///< bytes of all objects, without the unused tails of pages

  /// The shared-virtual-memory address of `page`'s first byte (Pager::at).
  std::uint64_t address(std::uint32_t page) const { return std::uint64_t(page) << page_shift; }
  /// The segment `page` (< pages) belongs to. (A segment without pages
  /// starts where the next one does, so no page is found in it.)
  Segment segment(std::uint32_t page) const {
    if (page >= block_first) return Segment::kBlocks;
    if (page >= normals_first) return Segment::kNormals;
    if (page >= primitive_first) return Segment::kPrimitives;
    if (page >= list_first) return Segment::kLists;
    if (page >= sub_grid_first) return Segment::kSubGrids;
    return Segment::kDirectory;
  }
  /// Bytes of the shared virtual memory (pages x page size).
  std::uint64_t bytes() const { return std::uint64_t(pages) * page_size; }
  /// The home node of a page among `nodes`, and the page's index there.
  static std::uint32_t home(std::uint32_t page, std::uint32_t nodes) { return page % nodes; }
  static std::uint32_t home_slot(std::uint32_t page, std::uint32_t nodes) { return page / nodes; }
  /// Pages whose home is `node`.
  std::uint32_t home_pages(std::uint32_t node, std::uint32_t nodes) const {
    return node < pages ? (pages - node + nodes - 1) / nodes : 0;
  }

  /// The directory key of cell (x, y, z) of `g` (the grid laid out).
  std::uint32_t directory_key(const core::GridInfo& g, std::int32_t x, std::int32_t y, std::int32_t z) const {
    return directory_order == DirectoryOrder::kBricked ? std::uint32_t(bricks.key(g, x, y, z)) : g.cell_index(x, y, z);
  }
  /// The page and offset of the directory entry with key `key`.
  std::uint32_t directory_page(std::uint32_t key) const { return directory_first + (key >> directory_shift); }
  std::uint32_t directory_offset(std::uint32_t key) const {
    return (key & ((1u << directory_shift) - 1)) * std::uint32_t(sizeof(DirectoryEntry));
  }
  /// The directory key of a grid's entry e (a cell of a uniform grid, or
  /// Grid::cell_entries' index of an adaptive one): the top grid's cells
  /// by directory_key, the sub-grids' cells after them in entry order.
  std::uint32_t entry_key(const core::GridInfo& top, std::uint32_t e) const {
    if (e >= top_cells) return top_keys + (e - top_cells);
    const std::uint32_t x = e % std::uint32_t(top.res[0]), yz = e / std::uint32_t(top.res[0]);
    return directory_key(top, std::int32_t(x), std::int32_t(yz % std::uint32_t(top.res[1])),
                         std::int32_t(yz / std::uint32_t(top.res[1])));
  }
  /// The shared-virtual-memory address of sub-grid record i.
  std::uint64_t sub_grid_address(std::uint32_t i) const {
    return address(sub_grid_first) + std::uint64_t(i) * sizeof(PagedSubGrid);
  }
  /// The page and offset of the record in primitive slot `id` (a
  /// primitive id in file order; in cell order, the slot the directory,
  /// lists and blocks name).
  std::uint32_t primitive_page(std::uint32_t id) const { return primitive_first + (id >> primitive_shift); }
  std::uint32_t primitive_offset(std::uint32_t id) const {
    return (id & ((1u << primitive_shift) - 1)) * std::uint32_t(sizeof(core::Primitive));
  }
  std::uint32_t normals_page(std::uint32_t id) const { return normals_first + id / normals_per_page; }
  std::uint32_t normals_offset(std::uint32_t id) const {
    return (id % normals_per_page) * std::uint32_t(sizeof(core::TriangleNormals));
  }
  std::uint32_t list_page(std::uint32_t address) const { return list_first + (address >> page_shift); }
  std::uint32_t list_offset(std::uint32_t address) const { return address & (page_size - 1); }
  /// The byte address in the blocks segment of block k of the packed run
  /// whose header is at `header`: in the header's page while whole blocks
  /// fit after it, then blocks_per_page blocks a page from each page's
  /// first byte.
  std::uint32_t packed_block_address(std::uint32_t header, std::uint32_t k) const {
    const std::uint32_t block = sizeof(core::TriangleBlock);
    const std::uint32_t first = (page_size - (header & (page_size - 1)) - kPackedHeaderBytes) / block;
    if (k < first) return header + kPackedHeaderBytes + k * block;
    k -= first;
    const std::uint32_t page = (header >> page_shift) + 1 + k / blocks_per_page;
    return (page << page_shift) + (k % blocks_per_page) * block;
  }
  std::uint32_t block_address_page(std::uint32_t address) const { return block_first + (address >> page_shift); }
  std::uint32_t block_address_offset(std::uint32_t address) const { return address & (page_size - 1); }
};

/// Builds the layout for a database and grid, with the packed cells of
/// `blocks` (built from the same db and grid) when given, the cell
/// directory in `order` (bricked: core::choose_cell_bricks for a page's
/// entries; its pages are the bricks, padding included) and the primitive
/// records in `primitive_order`. Throws
/// std::invalid_argument when page_size is not a power of two in
/// [kMinPageSize, kMaxPageSize] or, with blocks, below a run header and a
/// block (352 B), and std::length_error when the database needs more than
/// 2^32 pages, its lists or packed runs more than 1 GiB or its primitives
/// more than 2^30 ids (a directory entry's limits).
PageLayout make_page_layout(const core::Database& db, const core::Grid& grid, std::uint32_t page_size,
                            const core::CellBlocks* blocks = nullptr,
                            DirectoryOrder order = DirectoryOrder::kLinear,
                            PrimitiveOrder primitive_order = PrimitiveOrder::kFile);

/// Page-aligned host memory (mmap) that can be made unreadable: the host's
/// copy of the shared virtual memory, protected once the nodes are loaded
/// so that a node thread reading it faults instead of cheating.
class HostPages {
 public:
  HostPages() = default;
  /// `bytes` zeroed bytes. Throws std::bad_alloc.
  explicit HostPages(std::size_t bytes);
  HostPages(HostPages&& o) noexcept;
  HostPages& operator=(HostPages&& o) noexcept;
  HostPages(const HostPages&) = delete;
  HostPages& operator=(const HostPages&) = delete;
  ~HostPages();

  std::byte* data() { return data_; }
  const std::byte* data() const { return data_; }
  std::size_t size() const { return size_; }
  /// Makes every byte unreadable (PROT_NONE) until unprotect(). Throws
  /// std::system_error.
  void protect();
  void unprotect();
  bool is_protected() const { return protected_; }

 private:
  std::byte* data_ = nullptr;
  std::size_t size_ = 0;
  std::size_t mapped_ = 0;
  bool protected_ = false;
};

/// The host's image of the shared virtual memory.
struct PagedImage {
  PageLayout layout;
  HostPages pages;  ///< layout.pages x page_size bytes

  std::span<const std::byte> page(std::uint32_t p) const {
    return {pages.data() + std::size_t(p) * layout.page_size, layout.page_size};
  }
};

/// Lays out `db` and `grid`, uniform or adaptive (and the packed cells of
/// `blocks`, if given) in pages as described in the file comment. Same
/// errors as make_page_layout, and std::invalid_argument when `grid` lacks
/// its empty-space distances (core::build_grid computes them).
PagedImage build_paged_image(const core::Database& db, const core::Grid& grid, std::uint32_t page_size,
                             const core::CellBlocks* blocks = nullptr,
                             DirectoryOrder order = DirectoryOrder::kLinear,
                             PrimitiveOrder primitive_order = PrimitiveOrder::kFile);

/// The slot of each primitive id (slot[id], a permutation of 0..n-1) in
/// `l`'s primitive order: the identity in file order; in cell order, the
/// order in which the cells of `grid`, walked in `l`'s directory key order,
/// first list them, each cell's list in its order, and any primitive no
/// cell lists after them in id order.
std::vector<std::uint32_t> primitive_slots(const PageLayout& l, const core::Grid& grid, std::uint32_t primitives);

/// Each leaf cell's weight in list_primitive_pages: half its box's surface
/// area (world units squared), to which the chance that a ray crosses it
/// is proportional (the surface area heuristic's argument: MacDonald and
/// Booth, "Heuristics for ray tracing using space subdivision", 1990); a
/// sub-grid's large-primitive leaf, tested by every ray that enters the
/// sub-grid, gets the sub-grid's box's.
std::vector<double> leaf_weights(const core::Grid& grid);

/// Summed over the leaf cells of `grid`, each cell's weight (leaf_weights)
/// times the distinct primitive pages its list names when primitive id i
/// lies in slot[i] (pages of 2^shift records): up to a constant, the
/// primitive pages a ray reads per cell it tests, on average.
double list_primitive_pages(const core::Grid& grid, std::span<const double> weights,
                            std::span<const std::uint32_t> slot, std::uint32_t shift);

/// svm's automatic primitive order: cell order when list_primitive_pages is
/// lower with it than with file order (with `l`'s page size and directory
/// order), else file order. Cell order gathers a cell's primitives, but a
/// file written in a spatial order of its own (SPD Tetra's recursion, a
/// mesh's strips) can keep neighbouring cells' primitives together better;
/// where the file's order is not spatial (a shuffled or exported mesh) cell
/// order puts each list on a third as many pages.
PrimitiveOrder fewer_list_pages(const core::Grid& grid, PageLayout l);

}  // namespace raynode::svm
