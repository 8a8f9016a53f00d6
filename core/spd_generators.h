// Internal: one function per built-in SPD generator, dispatched by
// make_spd_scene (spd.cpp). Each returns the scene the SPD program writes
// with `-s size` (no -t; tessellation is applied afterwards by
// tessellate_scene). Throw std::invalid_argument for a size out of range.
#pragma once

#include "core/scene.h"

namespace raynode::core::spd {

Scene make_teapot(int size);  ///< spd_teapot.cpp; default size 2..
Scene make_mount(int size);   ///< spd_mount.cpp
Scene make_rings(int size);   ///< spd_rings.cpp
Scene make_tetra(int size);   ///< spd_tetra.cpp
Scene make_balls(int size);   ///< spd_balls.cpp

}  // namespace raynode::core::spd
