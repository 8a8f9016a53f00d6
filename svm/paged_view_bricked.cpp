// The tracer over BrickedPagedView, compiled once (core/render.h,
// RAYNODE_PIXEL_INSTANCES); a file of its own so that the two views'
// walks compile in parallel.
#include "svm/paged_view.h"

namespace raynode::core {
RAYNODE_PIXEL_INSTANCES(, svm::BrickedPagedView);
}  // namespace raynode::core
