#pragma once
/// \file Helpers of the BDPT tracer's translation units (bdpt_tracer.cpp,
/// bdpt_subpaths.cpp, bdpt_connect.cpp, bdpt_mis.cpp); not part of its interface.
#include "integrators/bdpt/path_vertex.h"
#include "materials/preview_surface.h"
#include "scene/interaction.h"

namespace cmlt::bdpt_detail {

/// The BSDF's transport mode for a subpath: light subpaths carry importance (it matters
/// for refraction only).
inline TransportMode mode_of(bool importance) {
    return importance ? TransportMode::Importance : TransportMode::Radiance;
}

/// Origin of a ray leaving vertex v in direction w (offset off surfaces).
inline Vec3 leave_point(const PathVertex& v, const Vec3& w) {
    if (v.type == VertexType::surface) return offset_ray_origin(v.p, v.si.ng, v.si.error_scale, w);
    if (v.on_surface()) return offset_ray_origin(v.p, v.ng, v.error_scale, w);
    return v.p;
}

}  // namespace cmlt::bdpt_detail
