// The diffuse fast path in structure-of-arrays lanes; see diffuse_lanes.h. Every
// expression below is the per-lane routine's (Scene::hit_geometry's place_triangle,
// PathTracer::scatter with Bsdf's Lambertian branch, Frame, offset_ray_origin), written
// component by component in the same order; where the routine branches, both sides are
// computed and one is selected.
#include "integrators/path/diffuse_lanes.h"

#include "integrators/path/path_tracer.h"
#include "materials/fresnel.h"
#include "materials/microfacet.h"
#include "materials/preview_surface.h"
#include "math/frame.h"
#include "math/safe_math.h"
#include "sampling/warp.h"
#include "scene/interaction.h"

#include <algorithm>
#include <cmath>
#include <limits>

#if defined(__AVX512F__)
#define CMLT_LANES_CLONES
#elif defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define CMLT_LANES_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define CMLT_LANES_CLONES
#endif
// the loops' helpers are inlined into every loop (a call keeps the loop scalar)
#if defined(__GNUC__)
#define CMLT_LANES_INLINE inline __attribute__((always_inline))
#else
#define CMLT_LANES_INLINE inline
#endif

namespace cmlt {

namespace {
/// std::isfinite without the library call (x − x is 0 exactly for finite x, NaN else).
inline bool finite(float x) { return x - x == 0.f; }
/// std::max(a, b) and std::min(a, b) as the standard defines them.
inline float fmax_std(float a, float b) { return a < b ? b : a; }
inline float fmin_std(float a, float b) { return b < a ? b : a; }
/// offset_ray_origin, one component: `side` is dot(w, n) < 0.
inline float offset(float p, float n, float e, bool side) {
    const float off = n * (k_offset_rel * e);
    return side ? p - off : p + off;
}
/// Bsdf's side test (consistent_sides, consistent_cosines) from the directions' dot
/// products with the geometric normal (go, gi) and the shading normal (lz, iz): neither
/// direction in the geometric plane, and the shading frame's sides agree with its.
CMLT_LANES_INLINE bool consistent(float go, float gi, float lz, float iz) {
    return (go != 0.f) & (gi != 0.f) & ((go * gi > 0.f) == (lz * iz > 0.f));
}
}  // namespace

CMLT_LANES_CLONES
void camera_directions(DiffuseLanes& L, size_t n, const PinholeConstants& c) {
    for (size_t k = 0; k < n; ++k) {
        Vec3 d;
        pinhole_ray(c, L.film_x[k], L.film_y[k], &d, &L.ray_tnear[k], &L.ray_tfar[k]);
        L.dx[k] = d.x;
        L.dy[k] = d.y;
        L.dz[k] = d.z;
    }
}

CMLT_LANES_CLONES
void diffuse_geometry(DiffuseLanes& L, size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
        // p from the barycentrics; error_scale = max_component(vmax(|p0|, vmax(|p1|, |p2|)))
        const float b1 = L.b1[i], b2 = L.b2[i], b0 = 1.f - b1 - b2;
        const float p0x = L.p0x[i], p0y = L.p0y[i], p0z = L.p0z[i];
        const float p1x = L.p1x[i], p1y = L.p1y[i], p1z = L.p1z[i];
        const float p2x = L.p2x[i], p2y = L.p2y[i], p2z = L.p2z[i];
        L.px[i] = p0x * b0 + p1x * b1 + p2x * b2;
        L.py[i] = p0y * b0 + p1y * b1 + p2y * b2;
        L.pz[i] = p0z * b0 + p1z * b1 + p2z * b2;
        const float ex = fmax_std(std::fabs(p0x), fmax_std(std::fabs(p1x), std::fabs(p2x)));
        const float ey = fmax_std(std::fabs(p0y), fmax_std(std::fabs(p1y), std::fabs(p2y)));
        const float ez = fmax_std(std::fabs(p0z), fmax_std(std::fabs(p1z), std::fabs(p2z)));
        L.err[i] = fmax_std(ex, fmax_std(ey, ez));
    }
    for (size_t i = begin; i < end; ++i) {
        // wo = -normalize(d)
        const float dx = L.dx[i], dy = L.dy[i], dz = L.dz[i];
        const float dl = std::sqrt(dx * dx + dy * dy + dz * dz);
        const float dr = 1.f / dl;
        const bool pos = dl > 0.f;
        L.wox[i] = -(pos ? dx * dr : 0.f);
        L.woy[i] = -(pos ? dy * dr : 0.f);
        L.woz[i] = -(pos ? dz * dr : 0.f);
    }
    for (size_t i = begin; i < end; ++i) {
        // ng = normalize(cross(p1 - p0, p2 - p0)), or wo for a degenerate triangle
        const float p0x = L.p0x[i], p0y = L.p0y[i], p0z = L.p0z[i];
        const float ax = L.p1x[i] - p0x, ay = L.p1y[i] - p0y, az = L.p1z[i] - p0z;
        const float bx = L.p2x[i] - p0x, by = L.p2y[i] - p0y, bz = L.p2z[i] - p0z;
        const float cx = ay * bz - az * by, cy = az * bx - ax * bz, cz = ax * by - ay * bx;
        const float cl = std::sqrt(cx * cx + cy * cy + cz * cz);
        const float cr = 1.f / cl;
        // (normalize gives 0 where cl is not positive, which counts as degenerate: the
        // quotient is needed only where cl > 0, so it is taken unconditionally)
        const float gx = cx * cr, gy = cy * cr, gz = cz * cr;
        const bool bad = (!(cl > 0.f)) | ((gx == 0.f) & (gy == 0.f) & (gz == 0.f)) |
                         !(finite(gx) & finite(gy) & finite(gz));
        const float wox = L.wox[i], woy = L.woy[i], woz = L.woz[i];
        L.ngx[i] = bad ? wox : gx;
        L.ngy[i] = bad ? woy : gy;
        L.ngz[i] = bad ? woz : gz;
    }
    for (size_t i = begin; i < end; ++i) {
        const float b1 = L.b1[i], b2 = L.b2[i], b0 = 1.f - b1 - b2;
        const float gx = L.ngx[i], gy = L.ngy[i], gz = L.ngz[i];
        // ns: the interpolated vertex normal by the normal matrix (double), normalised,
        // on ng's side; ng without vertex normals or where that fails
        const float mx = L.n0x[i] * b0 + L.n1x[i] * b1 + L.n2x[i] * b2;
        const float my = L.n0y[i] * b0 + L.n1y[i] * b1 + L.n2y[i] * b2;
        const float mz = L.n0z[i] * b0 + L.n1z[i] * b1 + L.n2z[i] * b2;
        const double x = mx, y = my, z = mz;
        const float tx = float(L.nm[0][i] * x + L.nm[1][i] * y + L.nm[2][i] * z);
        const float ty = float(L.nm[3][i] * x + L.nm[4][i] * y + L.nm[5][i] * z);
        const float tz = float(L.nm[6][i] * x + L.nm[7][i] * y + L.nm[8][i] * z);
        const float tl = std::sqrt(tx * tx + ty * ty + tz * tz);
        const float tr = 1.f / tl;
        const float ux = tx * tr, uy = ty * tr, uz = tz * tr;
        const bool use = (L.has_n[i] != 0) & (tl > 0.f) & !((ux == 0.f) & (uy == 0.f) & (uz == 0.f)) &
                         finite(ux) & finite(uy) & finite(uz);
        const bool flip = ux * gx + uy * gy + uz * gz < 0.f;
        const float fx = flip ? -ux : ux, fy = flip ? -uy : uy, fz = flip ? -uz : uz;
        L.nsx[i] = use ? fx : gx;
        L.nsy[i] = use ? fy : gy;
        L.nsz[i] = use ? fz : gz;
    }
}

/// A slot's light samples (sample_ok: valid, sample_w*: direction, sample_p*: point on the
/// light, sample_pdf: pmf times density; li the light's radiance) written where valid, as
/// the per-lane loop writes a LightSample (no normal, no error scale, finite distance, not
/// Dirac). (A loop of its own: with this merge in the sampling loop, that loop stays scalar.)
static void merge_slot_samples(DiffuseLanes& L, size_t n, float lr, float lg, float lb) {
    for (size_t i = 0; i < n; ++i) {
        const bool ok = L.sample_ok[i] != 0;
        L.ls_ok[i] = ok ? uint8_t(1) : L.ls_ok[i];
        L.wix[i] = ok ? L.sample_wx[i] : L.wix[i];
        L.wiy[i] = ok ? L.sample_wy[i] : L.wiy[i];
        L.wiz[i] = ok ? L.sample_wz[i] : L.wiz[i];
        L.li_r[i] = ok ? lr : L.li_r[i];
        L.li_g[i] = ok ? lg : L.li_g[i];
        L.li_b[i] = ok ? lb : L.li_b[i];
        L.plx[i] = ok ? L.sample_px[i] : L.plx[i];
        L.ply[i] = ok ? L.sample_py[i] : L.ply[i];
        L.plz[i] = ok ? L.sample_pz[i] : L.plz[i];
        L.light_pdf[i] = ok ? L.sample_pdf[i] : L.light_pdf[i];
    }
}

CMLT_LANES_CLONES
void rect_light_samples(DiffuseLanes& L, size_t n, uint8_t slot, const RectLightConstants& c) {
    // PlanarLight::sample_li with RectLight's sample_local and no texture or shaping (li is
    // the radiance times 1), then the per-lane loop's validity test (ls.valid() && pmf > 0)
    const double m00 = c.m[0][0], m01 = c.m[0][1], m02 = c.m[0][2], m03 = c.m[0][3];
    const double m10 = c.m[1][0], m11 = c.m[1][1], m12 = c.m[1][2], m13 = c.m[1][3];
    const double m20 = c.m[2][0], m21 = c.m[2][1], m22 = c.m[2][2], m23 = c.m[2][3];
    const float w = c.w, h = c.h, area = c.area;
    const float nx = c.n_emit.x, ny = c.n_emit.y, nz = c.n_emit.z;
    const float lr = c.radiance.x * 1.f, lg = c.radiance.y * 1.f, lb = c.radiance.z * 1.f;
    for (size_t i = 0; i < n; ++i) L.sample_slot[i] = L.rect_slot[i] == slot;
    for (size_t i = 0; i < n; ++i) {
        const double x = double((L.slot_ux[i] - 0.5f) * w), y = double((L.slot_uy[i] - 0.5f) * h), z = 0.0;
        const float qx = float(m00 * x + m01 * y + m02 * z + m03);
        const float qy = float(m10 * x + m11 * y + m12 * z + m13);
        const float qz = float(m20 * x + m21 * y + m22 * z + m23);
        const float dx = qx - L.px[i], dy = qy - L.py[i], dz = qz - L.pz[i];
        const float dist2 = dx * dx + dy * dy + dz * dz;
        const float r = 1.f / std::sqrt(dist2);
        const float wx = dx * r, wy = dy * r, wz = dz * r;
        const float cos_l = -(nx * wx + ny * wy + nz * wz);
        const float pdf = dist2 / (cos_l * area);
        const float pmf = L.slot_pmf[i];
        L.sample_ok[i] = (L.sample_slot[i] != 0) & (dist2 > 0.f) & (cos_l > 0.f) & finite(pdf) & (pdf > 0.f) &
                         (pmf > 0.f);
        L.sample_wx[i] = wx;
        L.sample_wy[i] = wy;
        L.sample_wz[i] = wz;
        L.sample_px[i] = qx;
        L.sample_py[i] = qy;
        L.sample_pz[i] = qz;
        L.sample_pdf[i] = pmf * pdf;
    }
    merge_slot_samples(L, n, lr, lg, lb);
}

namespace {
/// The tail of next-event estimation at lane i, given the BSDF's value times |cos| at the
/// light (f) and its density toward it: the pending shadow ray (none where there is no
/// light sample or f is black) — toward an infinite light spawn_ray(wi), else spawn_ray_to
/// the target offset off the light's surface toward the ray (shadow_target) — its BSDF
/// density (0 toward a Dirac light) and contribution beta * f * li.
CMLT_LANES_INLINE void next_event_shadow(DiffuseLanes& L, size_t i, float f_r, float f_g, float f_b, float bsdf_pdf) {
    const float wx = L.wix[i], wy = L.wiy[i], wz = L.wiz[i];
    const float gx = L.ngx[i], gy = L.ngy[i], gz = L.ngz[i];
    const bool sh = (L.ls_ok[i] != 0) & !((f_r == 0.f) & (f_g == 0.f) & (f_b == 0.f));
    L.shadow[i] = sh;
    const float px = L.px[i], py = L.py[i], pz = L.pz[i], e = L.err[i];
    const float nlx = L.nlx[i], nly = L.nly[i], nlz = L.nlz[i];
    const bool surf = !((nlx == 0.f) & (nly == 0.f) & (nlz == 0.f));
    const bool lside = (-wx) * nlx + (-wy) * nly + (-wz) * nlz < 0.f;
    const float qx = surf ? offset(L.plx[i], nlx, L.lerr[i], lside) : L.plx[i];
    const float qy = surf ? offset(L.ply[i], nly, L.lerr[i], lside) : L.ply[i];
    const float qz = surf ? offset(L.plz[i], nlz, L.lerr[i], lside) : L.plz[i];
    const bool inf = L.ls_inf[i];
    const float tx = inf ? wx : qx - px, ty = inf ? wy : qy - py, tz = inf ? wz : qz - pz;
    const bool side = tx * gx + ty * gy + tz * gz < 0.f;
    const float ox = offset(px, gx, e, side), oy = offset(py, gy, e, side), oz = offset(pz, gz, e, side);
    L.sox[i] = ox;
    L.soy[i] = oy;
    L.soz[i] = oz;
    L.sdx[i] = inf ? wx : qx - ox;
    L.sdy[i] = inf ? wy : qy - oy;
    L.sdz[i] = inf ? wz : qz - oz;
    L.stfar[i] = inf ? std::numeric_limits<float>::infinity() : 1.f - k_shadow_epsilon;
    L.shadow_bsdf_pdf[i] = L.ls_delta[i] ? 0.f : bsdf_pdf;
    L.sf_r[i] = L.beta_r[i] * f_r * L.li_r[i];
    L.sf_g[i] = L.beta_g[i] * f_g * L.li_g[i];
    L.sf_b[i] = L.beta_b[i] * f_b * L.li_b[i];
}

/// The tail of PathTracer::scatter at lane i for a sampled world direction w with value f
/// and density pdf (`ok`: Bsdf::sample's checks passed): beta *= f |cos| / pdf, the next
/// ray spawn_ray(w), Russian roulette from k_rr_start_depth; done where the sample or
/// the throughput is invalid or the roulette ends the path.
CMLT_LANES_INLINE void next_ray(DiffuseLanes& L, size_t i, float wx, float wy, float wz, float fr, float fg, float fb,
                     float pdf, bool ok) {
    const float gx = L.ngx[i], gy = L.ngy[i], gz = L.ngz[i];
    const float nx = L.nsx[i], ny = L.nsy[i], nz = L.nsz[i];
    // beta *= f * (|cos| / pdf)
    const float s = std::fabs(wx * nx + wy * ny + wz * nz) / pdf;
    const float br = L.beta_r[i] * (fr * s), bg = L.beta_g[i] * (fg * s), bb = L.beta_b[i] * (fb * s);
    ok = ok & !((br == 0.f) & (bg == 0.f) & (bb == 0.f)) & finite(br) & finite(bg) & finite(bb);
    // the next ray: spawn_ray(wi)
    const float px = L.px[i], py = L.py[i], pz = L.pz[i], e = L.err[i];
    const bool side = wx * gx + wy * gy + wz * gz < 0.f;
    L.rox[i] = offset(px, gx, e, side);
    L.roy[i] = offset(py, gy, e, side);
    L.roz[i] = offset(pz, gz, e, side);
    L.rdx[i] = wx;
    L.rdy[i] = wy;
    L.rdz[i] = wz;
    L.pdf[i] = pdf;
    // Russian roulette from k_rr_start_depth
    const bool roulette = L.depth[i] + 1 >= PathTracer::k_rr_start_depth;
    const float q = fmin_std(0.95f, fmax_std(br, fmax_std(bg, bb)) * L.eta_scale[i]);
    const bool killed = roulette & !(L.u_rr[i] < q);
    const float iq = 1.f / q;
    L.beta_r[i] = roulette ? br * iq : br;
    L.beta_g[i] = roulette ? bg * iq : bg;
    L.beta_b[i] = roulette ? bb * iq : bb;
    L.done[i] = !ok | killed;
}
}  // namespace

CMLT_LANES_CLONES
static void sphere_cones(DiffuseLanes& L, size_t n, uint8_t slot, const SphereLightConstants& c) {
    // SphereLight::sample_li up to its cone: the direction to the centre, its distance
    // (length: sqrt of the dot product), the cone's 1 - cos (sphere_cone_one_minus_cos, in
    // double)
    const float cx = c.center.x, cy = c.center.y, cz = c.center.z, r = c.radius;
    for (size_t i = 0; i < n; ++i) {
        const float tx = cx - L.px[i], ty = cy - L.py[i], tz = cz - L.pz[i];
        const float d = std::sqrt(tx * tx + ty * ty + tz * tz);
        const double s2 = double(r) * r / (double(d) * d);
        const double q = std::sqrt(1.0 - s2);
        const float omc = s2 >= 1.0 ? 1.f : float(s2 / (1.0 + q));
        const float id = 1.f / d;
        L.sample_slot[i] = L.sphere_slot[i] == slot;
        L.cone_omc[i] = L.sphere_slot[i] == slot ? omc : 0.f;
        L.cdist[i] = d;
        L.cnx[i] = tx * id;
        L.cny[i] = ty * id;
        L.cnz[i] = tz * id;
    }
}

CMLT_LANES_CLONES
static void sphere_cone_directions(DiffuseLanes& L, size_t n, uint8_t slot, float radius) {
    // the cone's direction (square_to_uniform_cone) where the point is outside the sphere
    for (size_t i = 0; i < n; ++i) {
        const bool in = (L.sphere_slot[i] == slot) & (L.cdist[i] > radius) & (L.cone_omc[i] > 0.f);
        const Vec3 v = square_to_uniform_cone(Vec2(L.slot_ux[i], L.slot_uy[i]), L.cone_omc[i]);
        L.cone_x[i] = in ? v.x : 0.f;
        L.cone_y[i] = in ? v.y : 0.f;
        L.cone_z[i] = in ? v.z : 0.f;
    }
}

CMLT_LANES_CLONES
static void sphere_finish(DiffuseLanes& L, size_t n, uint8_t slot, const SphereLightConstants& c) {
    // the rest of SphereLight::sample_li: the cone direction to the world (Frame of the
    // direction to the centre), normalised; the distance along it to the sphere
    // (hit_sphere, in double), or at the rim the tangent point's; li, the density, the point
    const double ccx = c.center.x, ccy = c.center.y, ccz = c.center.z, rr = double(c.radius) * c.radius;
    const float r = c.radius, lr = c.radiance.x * 1.f, lg = c.radiance.y * 1.f, lb = c.radiance.z * 1.f;
    for (size_t i = 0; i < n; ++i) {
        const Vec3 n(L.cnx[i], L.cny[i], L.cnz[i]);
        const Vec3 u = Frame(n).to_world(Vec3(L.cone_x[i], L.cone_y[i], L.cone_z[i]));
        const float ux = u.x, uy = u.y, uz = u.z;
        const float ul = std::sqrt(ux * ux + uy * uy + uz * uz);
        const float ur = 1.f / ul;
        const bool upos = ul > 0.f;
        const float wx = upos ? ux * ur : 0.f, wy = upos ? uy * ur : 0.f, wz = upos ? uz * ur : 0.f;
        // hit_sphere(p, wi)
        const float px = L.px[i], py = L.py[i], pz = L.pz[i];
        const double ox = double(px) - ccx, oy = double(py) - ccy, oz = double(pz) - ccz;
        const double a = double(wx) * wx + double(wy) * wy + double(wz) * wz;
        const double b = ox * wx + oy * wy + oz * wz;
        const double cc = ox * ox + oy * oy + oz * oz - rr;
        const double disc = b * b - a * cc;
        const double q = -b - std::sqrt(disc);
        // a miss as NaN (a hit's q / a is never NaN: q > 0, a > 0), so that the double
        // comparisons' masks stay apart from the floats' (mixed, the loop stays scalar)
        // (one select per test: a combination of the tests becomes booleans of two widths)
        double th = q / a;
        th = cc <= 0.0 ? double(NAN) : th;
        th = a <= 0.0 ? double(NAN) : th;
        th = disc < 0.0 ? double(NAN) : th;
        th = q <= 0.0 ? double(NAN) : th;
        const float tf = float(th);
        const float d = L.cdist[i];
        const float rim = d * fmax_std(0.f, dot(Vec3(wx, wy, wz), n));
        const float t = tf == tf ? tf : rim;
        const float omc = L.cone_omc[i];
        const float pdf = 1.f / (2.f * k_pi * omc);
        const float pmf = L.slot_pmf[i];
        L.sample_ok[i] = (L.sample_slot[i] != 0) & (d > r) & (omc > 0.f) & (pdf > 0.f) & (pmf > 0.f);
        L.sample_wx[i] = wx;
        L.sample_wy[i] = wy;
        L.sample_wz[i] = wz;
        L.sample_px[i] = px + wx * t;
        L.sample_py[i] = py + wy * t;
        L.sample_pz[i] = pz + wz * t;
        L.sample_pdf[i] = pmf * pdf;
    }
    merge_slot_samples(L, n, lr, lg, lb);
}

void sphere_light_samples(DiffuseLanes& L, size_t n, uint8_t slot, const SphereLightConstants& c) {
    sphere_cones(L, n, slot, c);
    sphere_cone_directions(L, n, slot, c.radius);
    sphere_finish(L, n, slot, c);
}

CMLT_LANES_CLONES
void diffuse_next_event(DiffuseLanes& L, size_t n) {
    for (size_t i = 0; i < n; ++i) {
        const float wox = L.wox[i], woy = L.woy[i], woz = L.woz[i];
        const float gx = L.ngx[i], gy = L.ngy[i], gz = L.ngz[i];
        const float sx = L.nsx[i], sy = L.nsy[i], sz = L.nsz[i];
        const float wx = L.wix[i], wy = L.wiy[i], wz = L.wiz[i];
        // Bsdf::eval's Lambertian branch (consistent_cosines), then |cos| at the light
        const float go = wox * gx + woy * gy + woz * gz, gi = wx * gx + wy * gy + wz * gz;
        const float lz = wox * sx + woy * sy + woz * sz, iz = wx * sx + wy * sy + wz * sz;
        const bool cons = consistent(go, gi, lz, iz);
        const bool lit = cons & !(lz * iz <= 0.f);
        const float c = std::fabs(iz);
        const float fr = lit ? L.rr[i] * k_inv_pi : 0.f, fg = lit ? L.rg[i] * k_inv_pi : 0.f,
                    fb = lit ? L.rb[i] * k_inv_pi : 0.f;
        // Bsdf::pdf's Lambertian branch
        next_event_shadow(L, i, fr * c, fg * c, fb * c, lit ? c * k_inv_pi : 0.f);
    }
}

CMLT_LANES_CLONES
void diffuse_sample(DiffuseLanes& L, size_t n) {
    for (size_t i = 0; i < n; ++i) {
        const float wox = L.wox[i], woy = L.woy[i], woz = L.woz[i];
        const float gx = L.ngx[i], gy = L.ngy[i], gz = L.ngz[i];
        const float nx = L.nsx[i], ny = L.nsy[i], nz = L.nsz[i];
        // LambertianBsdf::sample in the frame of ns (only lo.z enters)
        const float loz = wox * nx + woy * ny + woz * nz;
        const Vec2 disk = concentric_disk(L.u_bx[i], L.u_by[i]);  // sine and cosine: math/sincos.h
        const float ddx = disk.x, ddy = disk.y;
        float z = safe_sqrt(1.f - ddx * ddx - ddy * ddy);
        z = loz < 0.f ? -z : z;
        const float pdf = std::fabs(z) * k_inv_pi;
        const float fr = L.rr[i] * k_inv_pi, fg = L.rg[i] * k_inv_pi, fb = L.rb[i] * k_inv_pi;
        bool ok = (loz != 0.f) & (pdf > 0.f) & finite(fr) & finite(fg) & finite(fb);
        const Vec3 w = Frame(Vec3(nx, ny, nz)).to_world(Vec3(ddx, ddy, z));
        const float go = wox * gx + woy * gy + woz * gz, gi = w.x * gx + w.y * gy + w.z * gz;
        ok = ok & consistent(go, gi, loz, z);
        next_ray(L, i, w.x, w.y, w.z, fr, fg, fb, pdf, ok);
    }
}


namespace {

/// std::clamp(x, 0, 1).
CMLT_LANES_INLINE float clamp01_std(float x) { return x < 0.f ? 0.f : (1.f < x ? 1.f : x); }

/// Schlick's Fresnel of lane i's specular lobe, one channel (fresnel_schlick with its
/// weight w = schlick_weight(cos)).
CMLT_LANES_INLINE float schlick(float f0, float f90, float w) { return f0 + (f90 - f0) * w; }
CMLT_LANES_INLINE float schlick_w(float c) {
    const float m = clamp01_std(1.f - c);
    const float m2 = m * m;
    return m2 * m2 * m;
}

/// Lane i's model constants (PreviewSurfaceBsdf::LaneConstants), read once per loop body
/// and handed to the helpers by value.
struct LaneModel {
    float cdr, cdg, cdb, f0r, f0g, f0b, f90, alpha;
    float hd, hs;  ///< 1 or 0 (no bool members: see PreviewValue)
};
CMLT_LANES_INLINE LaneModel lane_model(const DiffuseLanes& L, size_t i) {
    return {L.cdr[i], L.cdg[i], L.cdb[i], L.f0r[i], L.f0g[i], L.f0b[i], L.f90[i], L.alpha[i],
            L.has_d[i], L.has_s[i]};
}

/// PreviewSurfaceBsdf::lobe_probabilities at |cos wo| = co for the lanes' model (no
/// clearcoat, opacity 1: the attenuation and the opacity factors are 1).
CMLT_LANES_INLINE void lobe_probabilities(const LaneModel& m, float co, float* pd, float* ps) {
    const float w = schlick_w(co);
    const float f90 = m.f90;
    const float fr = schlick(m.f0r, f90, w), fg = schlick(m.f0g, f90, w), fb = schlick(m.f0b, f90, w);
    const bool hd = m.hd != 0.f, hs = m.hs != 0.f;
    const float dr = m.cdr * (1.f - fr), dg = m.cdg * (1.f - fg), db = m.cdb * (1.f - fb);
    const float raw0 = hd ? (dr + dg + db) * (1.f / 3.f) : 0.f;
    const float raw1 = hs ? (fr + fg + fb) * (1.f / 3.f) : 0.f;
    const float total = raw0 + raw1;
    const float n_active = float(int(hd) + int(hs));
    const float uniform = (total > 0.f ? 0.1f : 1.f) / n_active;
    const float scale = total > 0.f ? (1.f - 0.1f) / total : 0.f;
    // an inactive lobe's probability is 0: the flag (1 or 0) as a factor rather than a
    // select, which the compiler would follow into the callers' "> 0" tests as a boolean
    // of another width (the loop would stay scalar). The product is exact: the sum is
    // finite, or NaN where |cos wo| is, and the callers only ask "> 0" of it, which NaN
    // and 0 both fail.
    *pd = (raw0 * scale + uniform) * m.hd;
    *ps = (raw1 * scale + uniform) * m.hs;
}

/// PreviewSurfaceBsdf::evaluate<true, true> for the lanes' model at local directions
/// (lo, li), its lobe probabilities at |lo.z| given: the value (f) and the density where
/// `ok`; where not, the model returns 0 for both (the callers select: a select of these
/// zeros that the compiler can follow into a boolean would keep the loop scalar).
struct PreviewValue {
    float r, g, b, pdf;
    int32_t ok;  ///< 1 or 0: a bool member would be an 8-bit mask beside the floats' 32-bit ones, which the vectoriser will not mix
};
CMLT_LANES_INLINE PreviewValue preview_value(const LaneModel& m, float pd, float ps, float lox, float loy, float loz,
                                             float lix, float liy, float liz) {
    const float co = std::fabs(loz), ci = std::fabs(liz);
    const bool ok = !((co < k_preview_min_cos) | (ci < k_preview_min_cos)) & (loz * liz > 0.f);
    // the two-sided opaque lobes: wo_u, wi_u (z made positive), wm = normalize(wo_u + wi_u)
    const float hx = lox + lix, hy = loy + liy, hz = co + ci;
    const float hl = std::sqrt(hx * hx + hy * hy + hz * hz);
    const float hr = 1.f / hl;
    const bool hpos = hl > 0.f;
    const float mx = hpos ? hx * hr : 0.f, my = hpos ? hy * hr : 0.f, mz = hpos ? hz * hr : 0.f;
    // GGX terms (ggx_terms seen from wo_u, smith_s of wi_u)
    const float a = m.alpha, a2 = a * a;
    const float t = mx * mx + my * my + a2 * mz * mz;
    const float d = (mz <= 0.f) | !(t > 0.f) ? 0.f : a2 / (k_pi * t * t);
    const float so = std::sqrt(a2 + (1.f - a2) * (co * co));
    const float g1 = 2.f / (std::fabs(co) + so);
    const float si = std::sqrt(a2 + (1.f - a2) * (ci * ci));
    const float den = so * std::fabs(ci) + si * std::fabs(co);
    const float no_fresnel = d * (den > 0.f ? 2.f / den : 0.f) * 0.25f;
    const float om = lox * mx + loy * my + co * mz;  // dot(wo_u, wm)
    // f: diffuse under the specular interface, then the specular lobe
    const bool hd = m.hd != 0.f, hs = m.hs != 0.f;
    const float f90 = m.f90, f0r = m.f0r, f0g = m.f0g, f0b = m.f0b;
    const float wo_w = schlick_w(co), wi_w = schlick_w(ci), wm_w = schlick_w(om);
    const float kr = m.cdr * (1.f - schlick(f0r, f90, wo_w)) * (1.f - schlick(f0r, f90, wi_w)) * k_inv_pi;
    const float kg = m.cdg * (1.f - schlick(f0g, f90, wo_w)) * (1.f - schlick(f0g, f90, wi_w)) * k_inv_pi;
    const float kb = m.cdb * (1.f - schlick(f0b, f90, wo_w)) * (1.f - schlick(f0b, f90, wi_w)) * k_inv_pi;
    const float sr = schlick(f0r, f90, wm_w) * no_fresnel, sg = schlick(f0g, f90, wm_w) * no_fresnel,
                sb = schlick(f0b, f90, wm_w) * no_fresnel;
    // (each sum below is the model's 0 + a + b with an inactive term 0: the terms are
    // never -0, so adding the 0 changes nothing)
    const float br = (hd ? kr : 0.f) + (hs ? sr : 0.f), bg = (hd ? kg : 0.f) + (hs ? sg : 0.f),
                bb = (hd ? kb : 0.f) + (hs ? sb : 0.f);
    // the density: reflection_pdf
    const float pdf_d = pd > 0.f ? pd * ci * k_inv_pi : 0.f;
    const float pdf_s = (ps > 0.f) & (om * co > 0.f) ? ps * (g1 * d * 0.25f) : 0.f;
    const float pdf = pdf_d + pdf_s;
    return {br, bg, bb, pdf, int32_t(ok)};
}
}  // namespace

CMLT_LANES_CLONES
void preview_frame(DiffuseLanes& L, size_t n) {
    for (size_t i = 0; i < n; ++i) {
        const float wox = L.wox[i], woy = L.woy[i], woz = L.woz[i];
        const Vec3 lo = Frame(Vec3(L.nsx[i], L.nsy[i], L.nsz[i])).to_local(Vec3(wox, woy, woz));
        L.lox[i] = lo.x;
        L.loy[i] = lo.y;
        L.loz[i] = lo.z;
        lobe_probabilities(lane_model(L, i), std::fabs(lo.z), &L.pd[i], &L.ps[i]);
    }
}

CMLT_LANES_CLONES
void preview_next_event(DiffuseLanes& L, size_t n) {
    for (size_t i = 0; i < n; ++i) {
        // Bsdf::eval_pdf: the side test (consistent_sides), then the model in the local
        // frame; times |cos| at the light
        const float wox = L.wox[i], woy = L.woy[i], woz = L.woz[i];
        const float gx = L.ngx[i], gy = L.ngy[i], gz = L.ngz[i];
        const float wx = L.wix[i], wy = L.wiy[i], wz = L.wiz[i];
        const Vec3 li = Frame(Vec3(L.nsx[i], L.nsy[i], L.nsz[i])).to_local(Vec3(wx, wy, wz));
        const float loz = L.loz[i];
        const float go = wox * gx + woy * gy + woz * gz, gi = wx * gx + wy * gy + wz * gz;
        const bool cons = consistent(go, gi, loz, li.z);
        const PreviewValue v =
            preview_value(lane_model(L, i), L.pd[i], L.ps[i], L.lox[i], L.loy[i], loz, li.x, li.y, li.z);
        const bool use = cons & (v.ok != 0);
        const float c = std::fabs(li.z);
        next_event_shadow(L, i, (use ? v.r : 0.f) * c, (use ? v.g : 0.f) * c, (use ? v.b : 0.f) * c,
                          use ? v.pdf : 0.f);
    }
}

CMLT_LANES_CLONES
void preview_directions(DiffuseLanes& L, size_t n) {
    // PreviewSurfaceBsdf::sample up to its evaluation: the lobe by u_lobe, then a cosine
    // direction (diffuse) or the reflection about a visible normal (specular), on wo's
    // side; both directions computed, the lobe's selected
    for (size_t i = 0; i < n; ++i) {
        const float wox = L.lox[i], woy = L.loy[i], woz = L.loz[i];
        const float pd = L.pd[i], ps = L.ps[i];
        const float u_rest = std::clamp(L.u_lobe[i], 0.f, k_one_minus_eps);
        const bool diffuse = (pd > 0.f) & ((u_rest < pd) | !(ps > 0.f));
        const float side = woz > 0.f ? 1.f : -1.f;
        const Vec2 u(L.u_bx[i], L.u_by[i]);
        const Vec3 wd = square_to_cosine_hemisphere(u);
        const Vec3 wo_u(wox, woy, std::fabs(woz));
        const Vec3 ws = reflect(wo_u, GgxDistribution(L.alpha[i]).sample_visible(wo_u, u));
        const bool grazing = std::fabs(woz) < k_preview_min_cos;
        const bool ok = (!grazing) & (diffuse | (ps > 0.f)) & (diffuse | (ws.z > 0.f));
        L.dir_ok[i] = ok;
        L.lix[i] = ok ? (diffuse ? wd.x : ws.x) : 0.f;
        L.liy[i] = ok ? (diffuse ? wd.y : ws.y) : 0.f;
        L.liz[i] = ok ? side * (diffuse ? wd.z : ws.z) : 0.f;
    }
}

CMLT_LANES_CLONES
void preview_sample(DiffuseLanes& L, size_t n) {
    // (in loops of their own: the value, then its checks — the compiler would follow the
    // value's selects into the finiteness tests as booleans of another width and keep the
    // loop scalar — then the throughput and next ray, then the reverse density)
    for (size_t i = 0; i < n; ++i) {
        // PreviewSurfaceBsdf::sample's value (where the model's value is 0 its density is
        // too, and the sample fails)
        const float liz = L.liz[i];
        const PreviewValue v =
            preview_value(lane_model(L, i), L.pd[i], L.ps[i], L.lox[i], L.loy[i], L.loz[i], L.lix[i], L.liy[i], liz);
        L.dir_ok[i] = (L.dir_ok[i] != 0) & !(std::fabs(liz) < k_preview_min_cos) & (v.ok != 0);
        L.sample_r[i] = v.r;
        L.sample_g[i] = v.g;
        L.sample_b[i] = v.b;
        L.pdf[i] = v.pdf;
    }
    for (size_t i = 0; i < n; ++i) {
        // its checks, then Bsdf::sample's
        const float wox = L.wox[i], woy = L.woy[i], woz = L.woz[i];
        const float gx = L.ngx[i], gy = L.ngy[i], gz = L.ngz[i];
        const float liz = L.liz[i];
        const float pdf = L.pdf[i];
        const bool ok = (L.dir_ok[i] != 0) & (pdf > 0.f) & finite(pdf) & finite(L.sample_r[i]) &
                        finite(L.sample_g[i]) & finite(L.sample_b[i]);
        const Vec3 w = Frame(Vec3(L.nsx[i], L.nsy[i], L.nsz[i])).to_world(Vec3(L.lix[i], L.liy[i], liz));
        const float go = wox * gx + woy * gy + woz * gz, gi = w.x * gx + w.y * gy + w.z * gz;
        L.dir_ok[i] = ok & consistent(go, gi, L.loz[i], liz);
        L.rdx[i] = w.x;
        L.rdy[i] = w.y;
        L.rdz[i] = w.z;
    }
    for (size_t i = 0; i < n; ++i)
        next_ray(L, i, L.rdx[i], L.rdy[i], L.rdz[i], L.sample_r[i], L.sample_g[i], L.sample_b[i], L.pdf[i],
                 L.dir_ok[i] != 0);
    for (size_t i = 0; i < n; ++i) {
        // Bsdf::pdf(wi, wo): the side test with the roles swapped, wi in the local frame
        // again (to_local of the world direction), the lobe probabilities at its cosine
        const float wox = L.wox[i], woy = L.woy[i], woz = L.woz[i];
        const float gx = L.ngx[i], gy = L.ngy[i], gz = L.ngz[i];
        const float wx = L.rdx[i], wy = L.rdy[i], wz = L.rdz[i];
        const float lox = L.lox[i], loy = L.loy[i], loz = L.loz[i];
        const float go = wox * gx + woy * gy + woz * gz, gi = wx * gx + wy * gy + wz * gz;
        const Vec3 ri = Frame(Vec3(L.nsx[i], L.nsy[i], L.nsz[i])).to_local(Vec3(wx, wy, wz));
        const bool rcons = consistent(gi, go, ri.z, loz);
        const LaneModel m = lane_model(L, i);
        float rpd, rps;
        lobe_probabilities(m, std::fabs(ri.z), &rpd, &rps);
        const PreviewValue r = preview_value(m, rpd, rps, ri.x, ri.y, ri.z, lox, loy, loz);
        L.pdf_rev[i] = rcons & (r.ok != 0) ? r.pdf : 0.f;
    }
}

}  // namespace cmlt
