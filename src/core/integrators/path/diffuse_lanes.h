#pragma once
/// \file The diffuse fast path of PathBatch in structure-of-arrays lanes: the hits of a
/// round that land on a constant-Lambertian triangle of a static instance are shaded
/// together, one loop per stage over all of them, each component of each quantity in an
/// array of its own, so that the compiler turns the loops into SIMD code.
///
/// The SIMD layer is deliberately the compiler's auto-vectoriser over plain SoA loops,
/// each kernel compiled for AVX2 and the portable baseline and chosen when the module
/// loads (GCC target_clones, as philox4x32_lanes): no intrinsics, no new dependency
/// (Highway or xsimd would bring their own dispatch and a second, hand-vectorised
/// formulation to keep equal to the scalar one), and the same source is the scalar
/// reference. The loops compute exactly the floats PathTracer::step(LambertHit)
/// computes — the same operations in the same order, branches written as selects
/// (computed on both sides, so the file is built without trapping-math and errno: no
/// change to any value), no contraction into fused multiply-adds (-ffp-contract=off) —
/// so a lane's path is the per-lane routine's bit for bit (tests/cpp: PathBatch against
/// PathTracer::li without packets). An AVX-512 clone was tried and dropped: with it the
/// frame ran at 0.91x the per-lane routine's speed, perf putting the scalar libm calls
/// that then followed (sincosf) at ten times their cost (tests/bench/results/profile.md).
/// The sines and cosines are the project's own polynomials now (math/sincos.h), shared
/// by the warps and the microfacet sampler, so the direction stages vectorise too; the
/// x86-64-v4 module's loops are compiled for its own level (AVX-512) without clones, the
/// same floats (fingerprint.py) and no slower (1.00-1.01x, 2026-12-07).
///
/// Stages, per round (PathBatch::trace_tile):
///   1. gather (PathBatch, scalar): ray, the triangle's corners (and corner normals with
///      the instance's normal matrix), barycentrics, reflectance, throughput, the
///      bounce's numbers;
///   2. diffuse_geometry: point, wo, geometric and shading normals, offset scale;
///   3. next-event sampling (PathBatch, scalar: one light by power, Light::sample_li —
///      virtual per light type — except for unshaped rect and sphere lights, whose samples
///      rect_light_samples and sphere_light_samples compute in lanes);
///   4. diffuse_next_event: the Lambertian value and density toward the light sample,
///      the shadow ray and its pending contribution;
///   5. diffuse_sample: the cosine-weighted direction in the shading frame (the
///      concentric map), the throughput, the next ray, Russian roulette;
///   6. scatter back into the lanes' PathState (PathBatch, scalar).
///
/// Hits on a constant preview BSDF (Scene::constant_preview: UsdPreviewSurface with
/// constant inputs) or on a material whose BSDF the uv alone makes (Scene::lane_material)
/// take stages 1 and 2 from the top of the arrays down. Where that BSDF is opaque with a
/// diffuse and/or rough GGX specular lobe and no clearcoat (PreviewSurfaceBsdf::
/// lane_constants: most production surfaces) the hit moves to the preview lanes (a
/// DiffuseLanes of its own, the preview_* stages below); the others are shaded by the
/// per-lane routine (PathTracer::step(BsdfHit)).
///
/// What gets these loops vectorised (GCC 12; `-fopt-info-vec` lists the loops it took):
/// no boolean the compiler can build from masks of two widths — a byte flag or a bool
/// member beside float comparisons, double comparisons combined with float ones, a value
/// zeroed by a select and then tested against zero — so flags are floats or 32-bit ints,
/// tests are applied one select at a time, and a value's checks or a merge into the
/// lanes' fields ("ok ? new : old", which stays a branch) run in loops of their own; sums
/// instead of nested selects; every helper inlined. Scalar still: the merges.
#include "cameras/camera.h"
#include "integrators/common/frame_loop.h"
#include "lights/light.h"

#include <cstddef>
#include <cstdint>

namespace cmlt {

struct DiffuseLanes {
    /// Lanes per call: a tile's pixels (PathBatch's lanes).
    static constexpr size_t k_capacity = size_t(k_tile_size) * size_t(k_tile_size);
    static constexpr size_t N = k_capacity;

    // 0. camera rays (camera_directions): the film positions in, the ray's direction
    // (dx, dy, dz) and its interval out
    alignas(64) float film_x[N], film_y[N], ray_tnear[N], ray_tfar[N];

    // 1. inputs
    alignas(64) float dx[N], dy[N], dz[N];           ///< ray direction
    alignas(64) float b1[N], b2[N];                  ///< barycentrics of corners 1 and 2
    alignas(64) float p0x[N], p0y[N], p0z[N], p1x[N], p1y[N], p1z[N], p2x[N], p2y[N], p2z[N];
    alignas(64) uint8_t has_n[N];                    ///< the mesh has vertex normals
    alignas(64) float n0x[N], n0y[N], n0z[N], n1x[N], n1y[N], n1z[N], n2x[N], n2y[N], n2z[N];
    alignas(64) double nm[9][N];                     ///< instance normal matrix, row-major 3x3
    alignas(64) float rr[N], rg[N], rb[N];           ///< reflectance
    alignas(64) float beta_r[N], beta_g[N], beta_b[N];
    alignas(64) float eta_scale[N];
    alignas(64) int32_t depth[N];
    alignas(64) float u_bx[N], u_by[N], u_rr[N];     ///< BSDF direction, roulette

    // 2. geometry
    alignas(64) float px[N], py[N], pz[N];
    alignas(64) float wox[N], woy[N], woz[N];
    alignas(64) float ngx[N], ngy[N], ngz[N];
    alignas(64) float nsx[N], nsy[N], nsz[N];
    alignas(64) float err[N];

    // 3. the light sample (ls_ok: sampled, valid, pmf > 0)
    alignas(64) uint8_t ls_ok[N], ls_delta[N], ls_inf[N];
    alignas(64) float wix[N], wiy[N], wiz[N];
    alignas(64) float li_r[N], li_g[N], li_b[N];
    alignas(64) float light_pdf[N];                  ///< pmf times the sample's pdf
    alignas(64) float plx[N], ply[N], plz[N], nlx[N], nly[N], nlz[N], lerr[N];
    /// 3b. a sample of a rect light with RectLightConstants (rect_light_samples) or of a
    /// sphere light with SphereLightConstants (sphere_light_samples): its slot among those
    /// lights (k_no_rect_slot: sampled one lane at a time, or none), its numbers and the
    /// light's pmf
    alignas(64) uint8_t rect_slot[N], sphere_slot[N];
    alignas(64) float slot_ux[N], slot_uy[N], slot_pmf[N];
    static constexpr uint8_t k_no_rect_slot = 0xFF;
    /// Rect lights and sphere lights per frame whose samples the lanes compute (PathBatch:
    /// the first ones of each kind by light index; a lane loop per slot).
    static constexpr size_t k_rect_slots = 4;
    /// 3c. a slot's samples before they are merged into the lanes' (rect_light_samples,
    /// sphere_light_samples): the lane's slot is the pass's, the sample is valid, its
    /// direction, point and pmf times density
    alignas(64) int32_t sample_slot[N], sample_ok[N];
    alignas(64) float sample_wx[N], sample_wy[N], sample_wz[N], sample_px[N], sample_py[N], sample_pz[N];
    alignas(64) float sample_pdf[N];
    /// sphere_light_samples' intermediates: the cone's 1 - cos, the unit direction to the
    /// centre and the distance to it, the direction in the cone's frame
    alignas(64) float cone_omc[N], cnx[N], cny[N], cnz[N], cdist[N], cone_x[N], cone_y[N], cone_z[N];

    // 4. the pending shadow ray
    alignas(64) uint8_t shadow[N];
    alignas(64) float sox[N], soy[N], soz[N], sdx[N], sdy[N], sdz[N], stfar[N];
    alignas(64) float sf_r[N], sf_g[N], sf_b[N];
    alignas(64) float shadow_bsdf_pdf[N];

    // 5. the next ray
    alignas(64) uint8_t done[N];
    alignas(64) float pdf[N];
    alignas(64) float rox[N], roy[N], roz[N], rdx[N], rdy[N], rdz[N];

    // The preview lanes (a DiffuseLanes of their own, PathBatch::m_preview_lanes): stage 1
    // adds the model's constants (PreviewSurfaceBsdf::LaneConstants), the path
    // partition's specular flag of the material and the lobe's number; rr/rg/rb unused.
    alignas(64) float cdr[N], cdg[N], cdb[N];        ///< Lambert colour
    alignas(64) float f0r[N], f0g[N], f0b[N], f90[N], alpha[N];
    alignas(64) float has_d[N], has_s[N];            ///< 1 or 0 (floats: masks of one width in the loops)
    alignas(64) int32_t spec[N];
    alignas(64) float u_lobe[N];
    // preview_frame: wo in the shading frame, the lobe probabilities at |lo.z|
    alignas(64) float lox[N], loy[N], loz[N], pd[N], ps[N];
    // preview_directions: the sampled direction in the shading frame (dir_ok: sampled)
    alignas(64) int32_t dir_ok[N];
    alignas(64) float lix[N], liy[N], liz[N];
    // preview_sample: the sample's value (its density in pdf, its direction in rd*)
    alignas(64) float sample_r[N], sample_g[N], sample_b[N];
    // preview_sample: the density of sampling wo from the next direction (Bsdf::pdf(wi, wo),
    // for the caustic light tracing's reverse densities)
    alignas(64) float pdf_rev[N];
};

/// The camera rays of a round's first lanes [0, n), before stage 1: Camera::generate_ray
/// of a pinhole (c) through (film_x, film_y), the same floats, its direction written to
/// dx, dy, dz and its interval to ray_tnear, ray_tfar (the origin is c.origin).
void camera_directions(DiffuseLanes& L, size_t n, const PinholeConstants& c);
/// Stage 2 over lanes [begin, end).
void diffuse_geometry(DiffuseLanes& L, size_t begin, size_t end);
/// Stage 3's rect light samples over lanes [0, n): for each lane with rect_slot[k] == slot,
/// RectLight::sample_li at (px, py, pz) with (slot_ux, slot_uy), written where valid (with
/// pmf > 0) as the per-lane loop writes a LightSample (ls_ok, wi, li, light_pdf, the point
/// on the light; no normal, no error scale, finite distance, not Dirac).
void rect_light_samples(DiffuseLanes& L, size_t n, uint8_t slot, const RectLightConstants& c);
/// Stage 3's sphere light samples over lanes [0, n), as rect_light_samples for lanes with
/// sphere_slot[k] == slot: SphereLight::sample_li (no normal, no error scale, not Dirac).
void sphere_light_samples(DiffuseLanes& L, size_t n, uint8_t slot, const SphereLightConstants& c);
/// Stage 4 over lanes [0, n) (lanes without ls_ok get no shadow ray).
void diffuse_next_event(DiffuseLanes& L, size_t n);
/// Stage 5 over lanes [0, n).
void diffuse_sample(DiffuseLanes& L, size_t n);

/// The preview lanes: hits on an opaque UsdPreviewSurface with a diffuse and/or rough GGX
/// specular lobe and no clearcoat (PreviewSurfaceBsdf::lane_constants), shaded as
/// PathTracer::step(BsdfHit) shades them — the same floats — with the model's value and
/// density (PreviewSurfaceBsdf::eval_pdf) computed in lanes. Stages 1-3 and 6 as above;
/// then over lanes [0, n):
///   preview_frame: wo in the shading frame and the lobe probabilities;
///   preview_next_event: the BSDF's value and density toward the light sample, the
///     shadow ray (as diffuse_next_event);
///   preview_directions: the lobe and the direction PreviewSurfaceBsdf::sample picks
///     (both lobes' directions, one selected; their sines and cosines: math/sincos.h);
///   preview_sample: the sample's value and density, the checks of Bsdf::sample, the
///     throughput, the next ray, Russian roulette, and the reverse density.
void preview_frame(DiffuseLanes& L, size_t n);
void preview_next_event(DiffuseLanes& L, size_t n);
void preview_directions(DiffuseLanes& L, size_t n);
void preview_sample(DiffuseLanes& L, size_t n);

}  // namespace cmlt
