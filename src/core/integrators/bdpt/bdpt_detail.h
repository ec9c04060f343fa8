#pragma once
/// \file Helpers of the BDPT tracer's translation units (bdpt_tracer.cpp,
/// bdpt_subpaths.cpp, bdpt_connect.cpp, bdpt_mis.cpp); not part of its interface. The
/// small BdptTracer members every unit calls per vertex are defined here, inline, so the
/// split into units costs no calls.
#include "integrators/bdpt/bdpt_tracer.h"
#include "integrators/bdpt/path_vertex.h"
#include "materials/bsdf.h"
#include "materials/preview_surface.h"
#include "scene/interaction.h"
#include "scene/scene.h"

#include <cmath>

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

namespace cmlt {

inline bool BdptTracer::is_delta_light(const PathVertex& v) const {
    return v.light_index >= 0 && m_scene.light(size_t(v.light_index)).is_delta();
}

inline bool BdptTracer::connectible(const PathVertex& v) const {
    switch (v.type) {
        case VertexType::surface: return v.bsdf && v.bsdf->has_non_delta();
        case VertexType::camera: return m_importance.connectable();
        case VertexType::light: return true;
    }
    return false;
}

inline float BdptTracer::convert_density(float pdf_sa, const PathVertex& from, const PathVertex& to) const {
    if (to.infinite) return pdf_sa;
    Vec3 w = to.p - from.p;
    float d2 = length_squared(w);
    if (!(d2 > 0.f)) return 0.f;
    float pdf = pdf_sa / d2;
    if (to.on_surface()) pdf *= std::fabs(dot(to.ng, w)) / std::sqrt(d2);
    return pdf;
}

}  // namespace cmlt
