#pragma once
/// \file A vertex of a BDPT subpath (Veach 1997 ch. 10; pbrt-v4's Vertex).
///
/// Densities `pdf_fwd` / `pdf_rev` are per unit *area* at the vertex (per solid angle
/// for an infinite-light vertex, which is a direction): `pdf_fwd` is the density with
/// which the vertex's own subpath generated it, `pdf_rev` the density with which the
/// other direction would (filled in when the next vertex is sampled, or overridden by
/// the MIS weight for the connection vertices). A vertex sampled through a Dirac lobe
/// has `delta` set and the densities of its two neighbours' edges set to 0 (they are
/// remapped to 1 in the ratios and strategies through it get no weight). Pass-through
/// crossings make no vertex; densities across them include `pass_pdf`.
#include "materials/bsdf.h"
#include "math/vec.h"
#include "scene/interaction.h"

#include <cstdint>
#include <optional>

namespace cmlt {

enum class VertexType : uint8_t { camera, light, surface };

struct PathVertex {
    VertexType type = VertexType::surface;
    bool delta = false;      ///< surface: left (or reached) through a Dirac lobe
    bool infinite = false;   ///< light: an infinite light (dome, distant): a direction
    Vec3 p;                  ///< position (unused for infinite lights)
    Vec3 ng;                 ///< geometric / emitter normal, zero for points (camera, point light)
    Vec3 ns;                 ///< shading normal (surfaces)
    Vec3 wo;                 ///< surfaces and hit lights: unit direction to the previous vertex
    Vec3 w_inf;              ///< infinite light: unit direction in which the light travels
    float error_scale = 0.f;
    float time = 0.f;        ///< shutter time of the sample (Ray::time of every ray it traces)
    Spectrum beta{0.f};      ///< subpath throughput up to (not including) this vertex's scattering
    Spectrum le{0.f};        ///< camera subpaths: radiance emitted toward `wo` (emitter hits)
    float pdf_fwd = 0.f, pdf_rev = 0.f;
    /// Product of the lobe probabilities of the pass-through surfaces (cut-outs, ior-1
    /// interfaces) crossed between the previous vertex of this subpath and this one:
    /// the walk's density factor for that segment in either direction (1: none).
    float pass_pdf = 1.f;
    int32_t light_index = -1;  ///< light vertex, or emissive surface's triangle light; -1 if none
    SurfaceInteraction si;     ///< surfaces
    std::optional<Bsdf> bsdf;  ///< surfaces

    /// As a default-constructed vertex of type `t`, except `si`, which keeps its old
    /// value: it is read only for surface vertices, and every surface vertex is given
    /// its own (this saves copying the 132-byte interaction for every vertex made).
    void reset(VertexType t) {
        type = t;
        delta = infinite = false;
        p = ng = ns = wo = w_inf = Vec3();
        error_scale = time = 0.f;
        beta = le = Spectrum(0.f);
        pdf_fwd = pdf_rev = 0.f;
        pass_pdf = 1.f;
        light_index = -1;
        bsdf.reset();
    }

    bool on_surface() const { return !is_black(ng); }
    bool is_light() const { return type == VertexType::light || light_index >= 0; }
};

}  // namespace cmlt
