#include "svm/paged_database.h"

#include <fmt/core.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cstring>
#include <new>
#include <stdexcept>
#include <string>
#include <system_error>
#include <utility>

namespace raynode::svm {

namespace {

constexpr std::uint32_t kNoSlot = 0xffffffffu;

bool is_packed(const core::CellBlocks* blocks, std::uint32_t cell) {
  return blocks && blocks->start[cell] != blocks->start[cell + 1];
}

/// Bytes of cell c's run in the lists segment: a header word and its ids
/// for an unpacked cell that lists two primitives or more, none for an
/// empty, one-primitive or packed cell.
std::uint64_t list_run_bytes(const core::Grid& grid, const core::CellBlocks* blocks, std::uint32_t c) {
  if (is_packed(blocks, c)) return 0;
  const std::uint64_t n = grid.cell_start[c + 1] - grid.cell_start[c];
  return n < 2 ? 0 : (1 + n) * sizeof(std::uint32_t);
}

/// Calls f(entry) for every directory entry of `grid` (its cells; for an
/// adaptive grid, the cells of every grid of the hierarchy) in the order of
/// their directory keys in `l` (l.directory_order, l.bricks): the top
/// grid's cells in the linear order, or brick by brick, each brick's cells
/// in linear order; then the sub-grids' cells in entry order.
template <class F>
void for_each_cell_in_key_order(const PageLayout& l, const core::Grid& grid, F&& f) {
  const core::GridInfo& g = grid.info;
  if (l.directory_order == DirectoryOrder::kLinear) {
    for (std::uint32_t c = 0; c < g.cell_count(); ++c) f(c);
  } else {
    const std::array<std::int32_t, 3>& d = l.bricks.dims;
    for (std::int32_t z0 = 0; z0 < g.res[2]; z0 += d[2])
      for (std::int32_t y0 = 0; y0 < g.res[1]; y0 += d[1])
        for (std::int32_t x0 = 0; x0 < g.res[0]; x0 += d[0])
          for (std::int32_t z = z0; z < std::min(z0 + d[2], g.res[2]); ++z)
            for (std::int32_t y = y0; y < std::min(y0 + d[1], g.res[1]); ++y)
              for (std::int32_t x = x0; x < std::min(x0 + d[0], g.res[0]); ++x) f(g.cell_index(x, y, z));
  }
  for (std::uint32_t e = g.cell_count(); e < l.cells; ++e) f(e);
}

/// The lists segment: every listed cell's run, cells in `l`'s key order
/// (so that a directory page's cells have their lists together), a list
/// that does not fit in the rest of the current page but fits in one page
/// on a fresh page (the file comment's rule); place(cell, byte address of
/// its header). Returns the segment's used bytes; throws std::length_error
/// past the 1 GiB a directory entry can address.
template <class Place>
std::uint64_t place_lists(const PageLayout& l, const core::Grid& grid, const core::CellBlocks* blocks, Place&& place) {
  const std::uint32_t page_size = l.page_size;
  std::uint64_t cursor = 0;
  for_each_cell_in_key_order(l, grid, [&](std::uint32_t c) {
    const std::uint64_t bytes = list_run_bytes(grid, blocks, c);
    if (bytes == 0) return;
    const std::uint64_t room = page_size - cursor % page_size;
    if (bytes > room && bytes <= page_size) cursor += room;  // keep a short list in one page
    if (cursor + bytes > std::uint64_t(kMaxEntryValue) + 1)
      throw std::length_error(fmt::format("svm: the cell lists need more than {} MiB ({} ids), the most a directory "
                                          "entry addresses",
                                          (std::uint64_t(kMaxEntryValue) + 1) >> 20, grid.references()));
    place(c, std::uint32_t(cursor));
    cursor += bytes;
  });
  return cursor;
}

/// The blocks segment: every packed cell's run (header and blocks, the
/// file comment's rule), cells in `l`'s key order; place(cell, byte
/// address of its header). Returns the segment's used bytes; throws
/// std::length_error past the 1 GiB a directory entry can address.
template <class Place>
std::uint64_t place_packed(const PageLayout& l, const core::Grid& grid, const core::CellBlocks& blocks,
                           Place&& place) {
  const std::uint32_t page_size = l.page_size;
  const std::uint64_t block = sizeof(core::TriangleBlock), per_page = page_size / block;
  std::uint64_t cursor = 0;
  for_each_cell_in_key_order(l, grid, [&](std::uint32_t c) {
    const std::uint64_t n = blocks.start[c + 1] - blocks.start[c];
    if (n == 0) return;
    const std::uint64_t bytes = kPackedHeaderBytes + n * block, in_page = cursor % page_size;
    if (in_page != 0 && bytes > page_size - in_page) cursor += page_size - in_page;  // a fresh page
    if (cursor > kMaxEntryValue)
      throw std::length_error(fmt::format("svm: the packed cells need more than {} MiB ({} blocks), the most a "
                                          "directory entry addresses",
                                          (std::uint64_t(kMaxEntryValue) + 1) >> 20, blocks.blocks.size()));
    place(c, std::uint32_t(cursor));
    if (bytes <= page_size) {
      cursor += bytes;
      return;
    }
    // Longer than a page: whole blocks after the header, then per_page a page.
    const std::uint64_t rest = n - (page_size - kPackedHeaderBytes) / block;
    cursor += page_size + (rest / per_page) * page_size + (rest % per_page) * block;
  });
  return cursor;
}

std::uint32_t pages_for(std::uint64_t bytes, std::uint32_t page_size) {
  return std::uint32_t((bytes + page_size - 1) / page_size);
}

}  // namespace

const char* segment_name(Segment s) {
  switch (s) {
    case Segment::kDirectory: return "directory";
    case Segment::kLists: return "lists";
    case Segment::kPrimitives: return "primitives";
    case Segment::kNormals: return "normals";
    case Segment::kBlocks: return "blocks";
    case Segment::kSubGrids: return "sub-grids";
  }
  return "?";
}

const char* primitive_order_name(PrimitiveOrder o) { return o == PrimitiveOrder::kCell ? "cell" : "file"; }

std::optional<PrimitiveOrder> parse_primitive_order(const std::string& text) {
  if (text == "auto") return std::nullopt;
  if (text == "file") return PrimitiveOrder::kFile;
  if (text == "cell") return PrimitiveOrder::kCell;
  throw std::invalid_argument(fmt::format("primitive order must be auto, file or cell, got '{}'", text));
}

std::vector<std::uint32_t> primitive_slots(const PageLayout& l, const core::Grid& grid, std::uint32_t primitives) {
  std::vector<std::uint32_t> slot(primitives);
  if (l.primitive_order == PrimitiveOrder::kFile) {
    for (std::uint32_t id = 0; id < primitives; ++id) slot[id] = id;
    return slot;
  }
  std::fill(slot.begin(), slot.end(), kNoSlot);
  std::uint32_t next = 0;
  const auto place = [&](std::uint32_t c) {
    for (std::uint32_t k = grid.cell_start[c]; k < grid.cell_start[c + 1]; ++k) {
      const std::uint32_t id = grid.cell_primitives[k];
      if (slot[id] == kNoSlot) slot[id] = next++;
    }
  };
  for_each_cell_in_key_order(l, grid, place);
  for (std::uint32_t& s : slot)
    if (s == kNoSlot) s = next++;
  return slot;
}

std::vector<double> leaf_weights(const core::Grid& grid) {
  const auto half_area = [](const core::Vec3& e) { return double(e.x) * e.y + double(e.y) * e.z + double(e.z) * e.x; };
  std::vector<double> w(grid.leaf_cells(), half_area(grid.info.cell_size));
  for (std::size_t i = 0; i < grid.sub_grids.size(); ++i) {
    const core::SubGrid& s = grid.sub_grids[i];
    std::fill_n(w.begin() + s.first_entry, s.info.cell_count(), half_area(s.info.cell_size));
    if (s.large_list) w[s.first_entry + s.info.cell_count()] = half_area(s.info.bounds.extent());
  }
  return w;  // a cell holding a sub-grid lists nothing: its weight is never used
}

double list_primitive_pages(const core::Grid& grid, std::span<const double> weights,
                            std::span<const std::uint32_t> slot, std::uint32_t shift) {
  double total = 0;
  std::vector<std::uint32_t> pages;
  for (std::uint32_t c = 0; c < grid.leaf_cells(); ++c) {
    pages.clear();
    for (std::uint32_t k = grid.cell_start[c]; k < grid.cell_start[c + 1]; ++k)
      pages.push_back(slot[grid.cell_primitives[k]] >> shift);
    std::sort(pages.begin(), pages.end());
    total += weights[c] * double(std::unique(pages.begin(), pages.end()) - pages.begin());
  }
  return total;
}

PrimitiveOrder fewer_list_pages(const core::Grid& grid, PageLayout l) {
  const std::vector<double> w = leaf_weights(grid);
  l.primitive_order = PrimitiveOrder::kFile;
  const double file = list_primitive_pages(grid, w, primitive_slots(l, grid, l.primitives), l.primitive_shift);
  l.primitive_order = PrimitiveOrder::kCell;
  const double cell = list_primitive_pages(grid, w, primitive_slots(l, grid, l.primitives), l.primitive_shift);
  return cell < file ? PrimitiveOrder::kCell : PrimitiveOrder::kFile;
}

const char* directory_order_name(DirectoryOrder o) {
  return o == DirectoryOrder::kBricked ? "bricked" : "linear";
}

std::optional<DirectoryOrder> parse_directory_order(const std::string& text) {
  if (text == "auto") return std::nullopt;
  if (text == "linear") return DirectoryOrder::kLinear;
  if (text == "bricked") return DirectoryOrder::kBricked;
  throw std::invalid_argument(fmt::format("directory order must be auto, linear or bricked, got '{}'", text));
}

PageLayout make_page_layout(const core::Database& db, const core::Grid& grid, std::uint32_t page_size,
                            const core::CellBlocks* blocks, DirectoryOrder order, PrimitiveOrder primitive_order) {
  if (page_size < kMinPageSize || page_size > kMaxPageSize || !std::has_single_bit(page_size))
    throw std::invalid_argument(fmt::format(
        "page size must be a power of two from {} B (one primitive record) to {} B, got {} B", kMinPageSize,
        kMaxPageSize, page_size));
  PageLayout l;
  l.page_size = page_size;
  l.page_shift = std::uint32_t(std::countr_zero(page_size));
  l.cells = grid.leaf_cells();
  l.top_cells = grid.info.cell_count();
  l.sub_grids = std::uint32_t(grid.sub_grids.size());
  if (l.sub_grids > kMaxEntryValue - core::kSubGridCode)
    throw std::length_error(fmt::format("svm: {} sub-grids, more than a directory entry can name", l.sub_grids));
  l.primitives = std::uint32_t(db.primitives.size());
  l.normal_sets = std::uint32_t(db.vertex_normals.size());
  l.blocks_per_page = page_size / std::uint32_t(sizeof(core::TriangleBlock));
  if (blocks && blocks->start.size() != std::size_t(l.cells) + 1)
    throw std::invalid_argument(fmt::format("svm: the packed cells are for {} cells, the grid has {}",
                                            blocks->start.size() - 1, l.cells));
  if (blocks && blocks->blocks.empty()) blocks = nullptr;  // nothing packed: the paper's layout
  if (blocks && page_size < kPackedHeaderBytes + sizeof(core::TriangleBlock))
    throw std::invalid_argument(fmt::format("page size {} B cannot hold a {}-byte block of packed triangles and its "
                                            "cell's {}-byte header (use --page-size 512 or more, or --pack-cells off)",
                                            page_size, sizeof(core::TriangleBlock), kPackedHeaderBytes));
  if (l.primitives > kMaxEntryValue + 1ull)
    throw std::length_error(fmt::format("svm: {} primitives, more than the 2^30 ids a directory entry holds",
                                        l.primitives));
  std::uint64_t listed = 0;
  for (std::uint32_t c = 0; c < l.cells; ++c) {
    const std::uint32_t n = grid.cell_start[c + 1] - grid.cell_start[c];  // 0 for a cell holding a sub-grid
    if (is_packed(blocks, c)) ++l.packed_cells;
    else if (n == 1) ++l.single_cells;
    else if (n > 1) {
      ++l.listed_cells;
      listed += n;
    }
  }
  l.list_ids = std::uint32_t(listed);
  l.directory_shift = std::uint32_t(std::countr_zero(page_size / std::uint32_t(sizeof(DirectoryEntry))));
  l.primitive_shift = std::uint32_t(std::countr_zero(page_size / std::uint32_t(sizeof(core::Primitive))));
  l.normals_per_page = page_size / std::uint32_t(sizeof(core::TriangleNormals));

  l.directory_order = order;
  l.primitive_order = primitive_order;
  if (order == DirectoryOrder::kBricked)
    l.bricks = core::choose_cell_bricks(grid.info, std::int32_t(1u << l.directory_shift));

  const std::uint64_t list_bytes = place_lists(l, grid, blocks, [](std::uint32_t, std::uint32_t) {});
  const std::uint64_t block_bytes =
      blocks ? place_packed(l, grid, *blocks, [](std::uint32_t, std::uint32_t) {}) : 0;
  if (block_bytes > 0xffffffffull)  // the blocks' byte addresses are 32-bit
    throw std::length_error(fmt::format("svm: the packed cells need more than 4 GiB ({} blocks)", blocks->blocks.size()));
  const std::uint64_t block_pages = pages_for(block_bytes, page_size);
  std::uint64_t top_keys = l.top_cells;
  if (order == DirectoryOrder::kBricked) top_keys = l.bricks.keys(grid.info);  // whole pages of bricks
  const std::uint64_t keys = top_keys + (l.cells - l.top_cells);
  if (keys > 0x7fffffffull)
    throw std::length_error(fmt::format("svm: a directory of {} entries does not fit 31-bit keys", keys));
  l.top_keys = std::uint32_t(top_keys);
  // The scene's large primitives beside the top grid: the leaf after its cells.
  if (!grid.sub_grids.empty() && grid.sub_grids[0].large_list) l.top_large_key = l.entry_key(grid.info, l.top_cells);
  const std::uint64_t dir_pages = (keys + (1u << l.directory_shift) - 1) >> l.directory_shift;
  const std::uint64_t sub_grid_pages = pages_for(std::uint64_t(l.sub_grids) * sizeof(PagedSubGrid), page_size);
  const std::uint64_t list_pages = pages_for(list_bytes, page_size);
  const std::uint64_t prim_pages = (std::uint64_t(l.primitives) + (1u << l.primitive_shift) - 1) >> l.primitive_shift;
  const std::uint64_t normal_pages =
      l.normals_per_page ? (std::uint64_t(l.normal_sets) + l.normals_per_page - 1) / l.normals_per_page : 0;
  if (l.normal_sets > 0 && l.normals_per_page == 0)
    throw std::invalid_argument(fmt::format("page size {} B cannot hold a 36-byte vertex-normal record", page_size));
  const std::uint64_t total = dir_pages + sub_grid_pages + list_pages + prim_pages + normal_pages + block_pages;
  if (total >= 0xffffffffull)
    throw std::length_error(fmt::format("svm: the database needs {} pages of {} B, more than 2^32", total, page_size));
  l.directory_first = 0;
  l.directory_pages = std::uint32_t(dir_pages);
  l.sub_grid_first = l.directory_first + l.directory_pages;
  l.sub_grid_pages = std::uint32_t(sub_grid_pages);
  l.list_first = l.sub_grid_first + l.sub_grid_pages;
  l.list_pages = std::uint32_t(list_pages);
  l.primitive_first = l.list_first + l.list_pages;
  l.primitive_pages = std::uint32_t(prim_pages);
  l.normals_first = l.primitive_first + l.primitive_pages;
  l.normals_pages = std::uint32_t(normal_pages);
  l.block_first = l.normals_first + l.normals_pages;
  l.block_pages = std::uint32_t(block_pages);
  if (blocks) {
    l.pack_min = blocks->min_triangles;
    l.blocks = std::uint32_t(blocks->blocks.size());
  }
  l.pages = std::uint32_t(total);
  l.object_bytes = std::uint64_t(l.cells) * sizeof(DirectoryEntry) + std::uint64_t(l.sub_grids) * sizeof(PagedSubGrid) +
                   (std::uint64_t(l.listed_cells) + l.list_ids) * sizeof(std::uint32_t) +
                   std::uint64_t(l.packed_cells) * kPackedHeaderBytes +
                   std::uint64_t(l.primitives) * sizeof(core::Primitive) +
                   std::uint64_t(l.normal_sets) * sizeof(core::TriangleNormals) +
                   std::uint64_t(l.blocks) * sizeof(core::TriangleBlock);
  return l;
}

PagedImage build_paged_image(const core::Database& db, const core::Grid& grid, std::uint32_t page_size,
                             const core::CellBlocks* blocks, DirectoryOrder order, PrimitiveOrder primitive_order) {
  if (grid.empty_distance.size() != grid.leaf_cells() || grid.leaf_cells() < grid.info.cell_count())
    throw std::invalid_argument(fmt::format("svm: the grid has {} empty-space distances for {} cells (not built by "
                                            "core::build_grid?)",
                                            grid.empty_distance.size(), grid.leaf_cells()));
  PagedImage image;
  image.layout = make_page_layout(db, grid, page_size, blocks, order, primitive_order);
  const PageLayout& l = image.layout;
  // Every primitive id the pages hold is its slot.
  const std::vector<std::uint32_t> slot = primitive_slots(l, grid, l.primitives);
  image.pages = HostPages(std::size_t(l.bytes()));
  std::byte* base = image.pages.data();
  auto at = [&](std::uint32_t page, std::uint32_t offset) { return base + (std::size_t(page) << l.page_shift) + offset; };

  // Directory: every cell's entry; lists: a header and the ids of every
  // cell that has a list; blocks: a header and the blocks of every packed
  // cell.
  if (l.blocks == 0) blocks = nullptr;
  auto put = [](std::byte* to, std::uint32_t word) { std::memcpy(to, &word, sizeof word); };
  const core::GridInfo& g = grid.info;
  auto entry = [&](std::uint32_t c) {
    const std::uint32_t key = l.entry_key(g, c);
    return at(l.directory_page(key), l.directory_offset(key));
  };
  const bool adaptive = l.sub_grids > 0;
  for (std::uint32_t c = 0; c < l.cells; ++c) {
    const std::uint32_t begin = grid.cell_start[c], end = grid.cell_start[c + 1];
    if (adaptive && (grid.cell_entries[c] & core::kSubGridEntry))
      put(entry(c), kEmptyCell | (core::kSubGridCode + (grid.cell_entries[c] & ~core::kSubGridEntry)));
    else if (begin == end) put(entry(c), kEmptyCell | grid.empty_distance[c]);
    else if (end - begin == 1 && !is_packed(blocks, c)) put(entry(c), kSingleCell | slot[grid.cell_primitives[begin]]);
  }
  std::byte* lists = at(l.list_first, 0);
  place_lists(l, grid, blocks, [&](std::uint32_t c, std::uint32_t address) {
    const std::uint32_t begin = grid.cell_start[c], end = grid.cell_start[c + 1];
    put(entry(c), kListCell | address);
    put(lists + address, end - begin);
    for (std::uint32_t k = begin; k < end; ++k) put(lists + address + 4 * (1 + k - begin), slot[grid.cell_primitives[k]]);
  });
  if (blocks) {
    std::byte* runs = at(l.block_first, 0);
    place_packed(l, grid, *blocks, [&](std::uint32_t c, std::uint32_t header) {
      put(entry(c), kPackedCell | header);
      put(runs + header, grid.cell_start[c + 1] - grid.cell_start[c]);  // the rest of the header stays zero
      std::uint32_t left = grid.cell_start[c + 1] - grid.cell_start[c];
      for (std::uint32_t k = blocks->start[c]; k < blocks->start[c + 1]; ++k, left -= core::kBlockLanes) {
        core::TriangleBlock b = blocks->blocks[k];
        for (std::uint32_t lane = 0; lane < std::min(left, core::kBlockLanes); ++lane) b.primitive[lane] = slot[b.primitive[lane]];
        std::memcpy(runs + l.packed_block_address(header, k - blocks->start[c]), &b, sizeof b);
      }
    });
  }
  // Sub-grid records: each grid's description and its cell 0's key.
  for (std::uint32_t i = 0; i < l.sub_grids; ++i) {
    const core::SubGrid& s = grid.sub_grids[i];
    const PagedSubGrid r{s.info, l.entry_key(g, s.first_entry) | (s.large_list ? kLargeListKey : 0u)};
    std::memcpy(base + l.sub_grid_address(i), &r, sizeof r);
  }
  // Primitives, each at its slot; then vertex normals, in the order of
  // their triangles' slots in cell order (the records renumbered to match).
  std::vector<std::uint32_t> by_slot(l.primitives);
  for (std::uint32_t id = 0; id < l.primitives; ++id) by_slot[slot[id]] = id;
  std::vector<std::uint32_t> normal_slot(l.normal_sets, kNoSlot);
  std::uint32_t next_normals = 0;
  for (std::uint32_t s = 0; s < l.primitives; ++s) {
    core::Primitive p = db.primitives[by_slot[s]];
    if (l.primitive_order == PrimitiveOrder::kCell && p.normals != core::kNoNormals && p.normals < l.normal_sets) {
      if (normal_slot[p.normals] == kNoSlot) normal_slot[p.normals] = next_normals++;
      p.normals = normal_slot[p.normals];
    }
    std::memcpy(at(l.primitive_page(s), l.primitive_offset(s)), &p, sizeof p);
  }
  for (std::uint32_t id = 0; id < l.normal_sets; ++id) {
    std::uint32_t to = id;
    if (l.primitive_order == PrimitiveOrder::kCell) {
      if (normal_slot[id] == kNoSlot) normal_slot[id] = next_normals++;  // a set no primitive names
      to = normal_slot[id];
    }
    std::memcpy(at(l.normals_page(to), l.normals_offset(to)), &db.vertex_normals[id], sizeof(core::TriangleNormals));
  }
  return image;
}

// --- HostPages -----------------------------------------------------------

HostPages::HostPages(std::size_t bytes) : size_(bytes) {
  if (bytes == 0) return;
  const std::size_t sys = std::size_t(sysconf(_SC_PAGESIZE));
  mapped_ = (bytes + sys - 1) / sys * sys;
  void* p = mmap(nullptr, mapped_, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) throw std::bad_alloc();
  data_ = static_cast<std::byte*>(p);
}

HostPages::HostPages(HostPages&& o) noexcept
    : data_(std::exchange(o.data_, nullptr)),
      size_(std::exchange(o.size_, 0)),
      mapped_(std::exchange(o.mapped_, 0)),
      protected_(std::exchange(o.protected_, false)) {}

HostPages& HostPages::operator=(HostPages&& o) noexcept {
  if (this != &o) {
    this->~HostPages();
    data_ = std::exchange(o.data_, nullptr);
    size_ = std::exchange(o.size_, 0);
    mapped_ = std::exchange(o.mapped_, 0);
    protected_ = std::exchange(o.protected_, false);
  }
  return *this;
}

HostPages::~HostPages() {
  if (data_) munmap(data_, mapped_);
  data_ = nullptr;
}

void HostPages::protect() {
  if (!data_ || protected_) return;
  if (mprotect(data_, mapped_, PROT_NONE) != 0) throw std::system_error(errno, std::generic_category(), "mprotect");
  protected_ = true;
}

void HostPages::unprotect() {
  if (!data_ || !protected_) return;
  if (mprotect(data_, mapped_, PROT_READ | PROT_WRITE) != 0)
    throw std::system_error(errno, std::generic_category(), "mprotect");
  protected_ = false;
}

}  // namespace raynode::svm
