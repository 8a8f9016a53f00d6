// The tracer over PagedView, compiled once (core/render.h,
// RAYNODE_PIXEL_INSTANCES).
#include "svm/paged_view.h"

namespace raynode::core {
RAYNODE_PIXEL_INSTANCES(, svm::PagedView);
}  // namespace raynode::core
