// Path tracing in batches; see path_batch.h.
#include "integrators/path/path_batch.h"

#include "accel/accel.h"
#include "cameras/camera.h"
#include "film/film.h"
#include "film/filter.h"
#include "film/pass_splatter.h"
#include "integrators/path/path_tracer_impl.h"
#include "scene/scene.h"

#include <optional>

namespace cmlt {

namespace {
/// Dimensions a lane prefetches per round: one bounce's (PathTracer::k_dims_per_bounce).
constexpr uint32_t k_prefetch = PathTracer::k_dims_per_bounce;

/// The first DiffuseLanes::k_rect_slots lights of a kind whose samples the lanes compute:
/// per light its slot (or k_no_rect_slot), per slot the constants `get` gives.
template <class Constants, class Get>
void lane_light_slots(const Scene& scene, std::vector<uint8_t>* slot, std::vector<Constants>* slots, Get&& get) {
    slot->assign(scene.light_count(), DiffuseLanes::k_no_rect_slot);
    for (size_t i = 0; i < scene.light_count() && slots->size() < DiffuseLanes::k_rect_slots; ++i) {
        Constants c;
        if (!get(scene.light(i), &c)) continue;
        (*slot)[i] = uint8_t(slots->size());
        slots->push_back(c);
    }
}
}  // namespace

template <class First>
void PathBatch::prefetch_dimensions(const std::vector<uint32_t>& lanes, uint32_t count, First&& first) {
    // Every lane's dimensions at once: Philox's numbers, or with a Sobol sequence the
    // dimensions' scramble seeds (sobol::scramble_seeds of (pixel, sequence_seed_sample,
    // d)), from which each lane's point follows (sampling/rng.h pixel_words)
    if (lanes.empty()) return;
    const PixelSequence seq = m_tracer.sequence();
    const bool sobol = low_discrepancy(seq);
    // a batch's lanes are samples of one index (trace_tile's s): one counter word for all;
    // with Sobol points, each lane's seed prefix (m_prefix, made by trace_tile) in place
    // of its pixel and that word
    const uint32_t sample = m_sampler[lanes[0]].sample();
    size_t n = 0;
    for (uint32_t l : lanes) {
        const uint32_t d0 = first(l);
        for (uint32_t k = 0; k < count; ++k, ++n) {
            m_c0[n] = sobol ? m_prefix[l] : m_sampler[l].pixel();
            m_c1[n] = sample;
            m_c2[n] = d0 + k;
        }
    }
    const Philox4x32Key key = seed_key(m_seed);
    if (sobol) {
        sobol::dimension_seeds_lanes(n, m_c0.data(), m_c2.data(), sobol::seed_key_hash(key[0], key[1]), m_w0.data(),
                                     m_w1.data());
        sobol::scrambled_points_lanes(n, sequence_index(seq, sample), m_w0.data(), m_w1.data());
    } else {
        philox4x32_lanes(n, m_c0.data(), m_c1.data(), m_c2.data(), uint32_t(RngStream::camera_path), key,
                         m_w0.data(), m_w1.data());
    }
    n = 0;
    for (uint32_t l : lanes) {
        uint32_t* w = &m_words[size_t(l) * 2 * k_prefetch];
        for (uint32_t k = 0; k < count; ++k, ++n) {
            w[2 * k] = m_w0[n];
            w[2 * k + 1] = m_w1[n];
        }
        m_sampler[l].prefetch(first(l), count, w);
    }
}

PathBatch::PathBatch(const PathTracer& tracer, const Scene& scene, const Camera& camera, const PixelFilter& filter,
                     bool motion_blur, uint64_t seed, int width, int height, int reach, int packet_width,
                     KeyShift shift)
    : m_tracer(tracer), m_scene(scene), m_camera(camera), m_filter(filter), m_motion_blur(motion_blur),
      m_seed(seed), m_width(width), m_height(height), m_reach(reach), m_shift(shift),
      m_packet_width(packet_width) {
    const size_t n = size_t(k_tile_size) * size_t(k_tile_size);
    m_pinhole_lanes = !motion_blur && camera.pinhole_constants(&m_pinhole);
    m_state.resize(n);
    m_sampler.assign(n, PixelSampler(0, 0, 0));
    m_pixel.resize(n);
    m_rays.resize(n);
    m_hits.resize(n);
    m_occluded.resize(n);
    m_skip_light.assign(n, k_invalid_id);
    m_prefix.resize(n);
    m_live.reserve(n);
    m_shadowed.reserve(n);
    m_scattering.reserve(n);
    m_pending.reserve(n);
    m_ended.reserve(n);
    for (auto* v : {&m_c0, &m_c1, &m_c2, &m_w0, &m_w1}) v->resize(n * k_prefetch);
    m_words.resize(n * 2 * k_prefetch);
    m_lanes.reset(new DiffuseLanes);  // not value-initialised: every lane is written before it is read
    m_diffuse.reserve(n);
    m_diffuse_light.resize(n);
    m_placed.reserve(n);
    m_placed_material.reserve(n);
    m_placed_preview.reserve(n);
    m_placed_uv.reserve(n);
    m_preview_lanes.reset(new DiffuseLanes);
    m_preview.reserve(n);
    m_preview_light.resize(n);
    m_lane_model.assign(scene.material_count(), 0);
    m_lane_constants.resize(scene.material_count());
    for (uint32_t i = 0; i < scene.material_count(); ++i) {
        const PreviewSurfaceBsdf* preview = scene.constant_preview(i);
        m_lane_model[i] = preview && preview->lane_constants(&m_lane_constants[i]);
    }
    lane_light_slots(scene, &m_rect_slot, &m_rect, [](const Light& l, RectLightConstants* c) { return l.rect_constants(c); });
    lane_light_slots(scene, &m_sphere_slot, &m_sphere,
                     [](const Light& l, SphereLightConstants* c) { return l.sphere_constants(c); });
}

bool PathBatch::gather_diffuse(uint32_t l, PathCounters& c) {
    // Stage 1 of diffuse_lanes.h for lane l, if its hit is a static instance's triangle
    // with a constant Lambertian (the diffuse lanes), a constant preview BSDF of the
    // preview lanes' model (those lanes), or a material the lanes place (another constant
    // preview BSDF, or one make_bsdf_at makes from the uv: no primvars). A path at its
    // last scattering event on one of the first two ends here (PathTracer::step).
    const Hit& h = m_hits[l];
    TriangleCorners tri;
    if (!m_scene.triangle_corners(h, &tri)) return false;
    const Spectrum* r = m_scene.constant_lambert(tri.material_id);
    // a constant preview BSDF of the preview lanes' model goes straight to those lanes
    const bool model = !r && m_lane_model[tri.material_id];
    const PreviewSurfaceBsdf* preview = r || model ? nullptr : m_scene.constant_preview(tri.material_id);
    const bool placed = !r && !model && (preview || (!tri.primvars && m_scene.lane_material(tri.material_id)));
    if (!r && !model && !placed) return false;
    PathState& st = m_state[l];
    ++m_lane_hits;
    DiffuseLanes& L = model ? *m_preview_lanes : *m_lanes;
    size_t k;
    if (placed) {
        k = DiffuseLanes::k_capacity - 1 - m_placed.size();
        m_placed.push_back(l);
        m_placed_preview.push_back(preview);
        m_placed_material.push_back(tri.material_id);
        // the texture coordinates as Scene::fill_interaction gives them
        m_placed_uv.push_back(hit_uv(tri.uv, 1.f - h.u - h.v, h.u, h.v));
    } else {
        if (st.depth == m_tracer.max_depth()) {
            ++st.bounce;
            c.rays += 1;
            st.done = true;
            return true;
        }
        std::vector<uint32_t>& lanes = model ? m_preview : m_diffuse;
        k = lanes.size();
        lanes.push_back(l);
    }
    const Ray& ray = m_rays[l];
    L.dx[k] = ray.d.x;
    L.dy[k] = ray.d.y;
    L.dz[k] = ray.d.z;
    L.b1[k] = h.u;
    L.b2[k] = h.v;
    L.p0x[k] = tri.p[0].x, L.p0y[k] = tri.p[0].y, L.p0z[k] = tri.p[0].z;
    L.p1x[k] = tri.p[1].x, L.p1y[k] = tri.p[1].y, L.p1z[k] = tri.p[1].z;
    L.p2x[k] = tri.p[2].x, L.p2y[k] = tri.p[2].y, L.p2z[k] = tri.p[2].z;
    L.has_n[k] = tri.normal != nullptr;
    if (tri.normal) {
        L.n0x[k] = tri.n[0][0], L.n0y[k] = tri.n[0][1], L.n0z[k] = tri.n[0][2];
        L.n1x[k] = tri.n[1][0], L.n1y[k] = tri.n[1][1], L.n1z[k] = tri.n[1][2];
        L.n2x[k] = tri.n[2][0], L.n2y[k] = tri.n[2][1], L.n2z[k] = tri.n[2][2];
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) L.nm[3 * a + b][k] = tri.normal->m[a][b];
    } else {
        L.n0x[k] = L.n0y[k] = L.n0z[k] = L.n1x[k] = L.n1y[k] = L.n1z[k] = 0.f;
        L.n2x[k] = L.n2y[k] = L.n2z[k] = 0.f;
        for (int a = 0; a < 9; ++a) L.nm[a][k] = 0.0;
    }
    if (placed) return true;
    if (model) {
        set_model(L, k, m_lane_constants[tri.material_id], tri.material_id);
        set_path(L, k, l);
        return true;
    }
    L.rr[k] = r->x;
    L.rg[k] = r->y;
    L.rb[k] = r->z;
    set_path(L, k, l);
    return true;
}

void PathBatch::set_path(DiffuseLanes& L, size_t k, uint32_t l) const {
    const PathState& st = m_state[l];
    L.beta_r[k] = st.beta.x;
    L.beta_g[k] = st.beta.y;
    L.beta_b[k] = st.beta.z;
    L.eta_scale[k] = st.eta_scale;
    L.depth[k] = st.depth;
    // the bounce's numbers (PathTracer::scatter: light, light position, BSDF direction,
    // lobe, roulette), prefetched for this round
    const uint32_t* w = &m_words[size_t(l) * 2 * k_prefetch];
    L.u_bx[k] = uint_to_unit_float(w[4]);
    L.u_by[k] = uint_to_unit_float(w[5]);
    L.u_lobe[k] = uint_to_unit_float(w[6]);
    L.u_rr[k] = uint_to_unit_float(w[8]);
}

void PathBatch::set_model(DiffuseLanes& L, size_t k, const PreviewSurfaceBsdf::LaneConstants& pc,
                          uint32_t material_id) const {
    L.cdr[k] = pc.diffuse.x, L.cdg[k] = pc.diffuse.y, L.cdb[k] = pc.diffuse.z;
    L.f0r[k] = pc.f0.x, L.f0g[k] = pc.f0.y, L.f0b[k] = pc.f0.z;
    L.f90[k] = pc.f90;
    L.alpha[k] = pc.alpha;
    L.has_d[k] = pc.has_diffuse ? 1.f : 0.f;
    L.has_s[k] = pc.has_specular ? 1.f : 0.f;
    const PathPartition* partition = m_tracer.partition();
    L.spec[k] = partition && partition->specular(material_id);
}

void PathBatch::shade_diffuse_lanes(PathCounters& c) {
    DiffuseLanes& L = *m_lanes;
    DiffuseLanes& P = *m_preview_lanes;
    const PathPartition* partition = m_tracer.partition();
    // the preview lanes gathered so far (constant BSDFs), then those the placed lanes add
    diffuse_geometry(P, 0, m_preview.size());
    if (!m_placed.empty()) {
        // the lanes from the top of the arrays down: placed here; those whose BSDF (made
        // from the uv) is the preview lanes' model go to those lanes, the others are shaded
        // one at a time by the per-lane routine with the BSDF make_bsdf would make
        const size_t top = DiffuseLanes::k_capacity;
        diffuse_geometry(L, top - m_placed.size(), top);
        for (size_t j = 0; j < m_placed.size(); ++j) {
            const size_t k = top - 1 - j;
            const uint32_t l = m_placed[j];
            PathState& st = m_state[l];
            HitGeometry g;
            g.sp.p = Vec3(L.px[k], L.py[k], L.pz[k]);
            g.sp.ng = Vec3(L.ngx[k], L.ngy[k], L.ngz[k]);
            g.sp.error_scale = L.err[k];
            g.sp.time = st.ray.time;
            g.ns = Vec3(L.nsx[k], L.nsy[k], L.nsz[k]);
            g.wo = Vec3(L.wox[k], L.woy[k], L.woz[k]);
            g.material_id = m_placed_material[j];
            std::optional<Bsdf> made;
            const PreviewSurfaceBsdf* model = m_placed_preview[j];
            if (!model) {
                made.emplace(make_bsdf_at(m_scene.material(g.material_id), m_placed_uv[j], g.ns, g.sp.ng,
                                          m_scene.textures(), nullptr, 0));
                model = made->preview();
            }
            PreviewSurfaceBsdf::LaneConstants pc;
            if (model && model->lane_constants(&pc)) {
                if (st.depth == m_tracer.max_depth()) {  // PathTracer::enter_opaque_hit
                    ++st.bounce;
                    c.rays += 1;
                    st.done = true;
                    continue;
                }
                const size_t q = m_preview.size();
                m_preview.push_back(l);
                P.px[q] = L.px[k], P.py[q] = L.py[k], P.pz[q] = L.pz[k], P.err[q] = L.err[k];
                P.wox[q] = L.wox[k], P.woy[q] = L.woy[k], P.woz[q] = L.woz[k];
                P.ngx[q] = L.ngx[k], P.ngy[q] = L.ngy[k], P.ngz[q] = L.ngz[k];
                P.nsx[q] = L.nsx[k], P.nsy[q] = L.nsy[k], P.nsz[q] = L.nsz[k];
                set_model(P, q, pc, g.material_id);
                set_path(P, q, l);
                continue;
            }
            if (!made) made.emplace(*m_placed_preview[j], g.ns, g.sp.ng);
            m_tracer.step(st, BsdfHit{&g, &*made}, m_sampler[l], c);
        }
    }
    if (!m_preview.empty()) {
        const size_t n = m_preview.size();
        preview_frame(P, n);
        const bool lights = m_scene.light_count() > 0;
        light_samples(P, m_preview, m_preview_light, [&](size_t q, const PathState& st) {
            return lights && (!partition || st.wants_next_event(*partition, P.spec[q] != 0));
        });
        preview_next_event(P, n);
        preview_directions(P, n);
        preview_sample(P, n);
        scatter_lanes(P, m_preview, m_preview_light, true, c);
    }
    const size_t n = m_diffuse.size();
    if (n == 0) return;
    diffuse_geometry(L, 0, n);
    // next-event estimation, with a partition only where it wants the path
    // (PathTracer::scatter: a Lambertian vertex is never specular, so the path through it
    // is not a caustic one)
    const bool nee = m_scene.light_count() > 0 && (!partition || partition->wants(partition->caustic(false, false, false, 1)));
    light_samples(L, m_diffuse, m_diffuse_light, [nee](size_t, const PathState&) { return nee; });
    diffuse_next_event(L, n);
    diffuse_sample(L, n);
    scatter_lanes(L, m_diffuse, m_diffuse_light, false, c);
}

template <class Wants>
void PathBatch::light_samples(DiffuseLanes& L, const std::vector<uint32_t>& lanes, std::vector<uint32_t>& light,
                              Wants&& wants) {
    // Stage 3: next-event estimation's light sample where wants(k, state) (and from the
    // partition's minimum depth), one lane at a time, except the rect lights' samples
    const size_t n = lanes.size();
    for (size_t k = 0; k < n; ++k) {
        const uint32_t l = lanes[k];
        const PathState& st = m_state[l];
        L.ls_ok[k] = 0;
        L.ls_inf[k] = 0;
        L.ls_delta[k] = 0;
        L.wix[k] = L.wiy[k] = L.wiz[k] = 0.f;
        L.li_r[k] = L.li_g[k] = L.li_b[k] = 0.f;
        L.plx[k] = L.ply[k] = L.plz[k] = L.nlx[k] = L.nly[k] = L.nlz[k] = L.lerr[k] = 0.f;
        L.light_pdf[k] = 0.f;
        L.rect_slot[k] = L.sphere_slot[k] = DiffuseLanes::k_no_rect_slot;
        L.slot_ux[k] = L.slot_uy[k] = L.slot_pmf[k] = 0.f;
        if (st.depth + 1 < m_tracer.min_depth() || !wants(k, st)) continue;
        const uint32_t* w = &m_words[size_t(l) * 2 * k_prefetch];
        float pmf = 0.f;
        const size_t li = m_scene.sample_light(uint_to_unit_float(w[0]), &pmf);
        if (m_rect_slot[li] != DiffuseLanes::k_no_rect_slot || m_sphere_slot[li] != DiffuseLanes::k_no_rect_slot) {
            // sampled below, in rect_light_samples or sphere_light_samples
            light[k] = uint32_t(li);
            L.rect_slot[k] = m_rect_slot[li];
            L.sphere_slot[k] = m_sphere_slot[li];
            L.slot_ux[k] = uint_to_unit_float(w[2]);
            L.slot_uy[k] = uint_to_unit_float(w[3]);
            L.slot_pmf[k] = pmf;
            continue;
        }
        const LightSample ls = m_scene.light(li).sample_li(
            Vec3(L.px[k], L.py[k], L.pz[k]), Vec2(uint_to_unit_float(w[2]), uint_to_unit_float(w[3])));
        if (!(ls.valid() && pmf > 0.f)) continue;
        light[k] = uint32_t(li);
        L.ls_ok[k] = 1;
        L.ls_inf[k] = std::isinf(ls.dist);
        L.ls_delta[k] = ls.is_delta;
        L.wix[k] = ls.wi.x, L.wiy[k] = ls.wi.y, L.wiz[k] = ls.wi.z;
        L.li_r[k] = ls.li.x, L.li_g[k] = ls.li.y, L.li_b[k] = ls.li.z;
        L.plx[k] = ls.p_light.x, L.ply[k] = ls.p_light.y, L.plz[k] = ls.p_light.z;
        L.nlx[k] = ls.n_light.x, L.nly[k] = ls.n_light.y, L.nlz[k] = ls.n_light.z;
        L.lerr[k] = ls.error_scale;
        L.light_pdf[k] = pmf * ls.pdf;
    }
    for (size_t s = 0; s < m_rect.size(); ++s) rect_light_samples(L, n, uint8_t(s), m_rect[s]);
    for (size_t s = 0; s < m_sphere.size(); ++s) sphere_light_samples(L, n, uint8_t(s), m_sphere[s]);
}

void PathBatch::scatter_lanes(const DiffuseLanes& L, const std::vector<uint32_t>& lanes,
                              const std::vector<uint32_t>& light, bool preview, PathCounters& c) {
    // Stage 6: back into the lanes' paths.
    const CausticLightTracing* caustic = m_tracer.caustic_light_tracing();
    const size_t n = lanes.size();
    for (size_t k = 0; k < n; ++k) {
        PathState& st = m_state[lanes[k]];
        const float time = st.ray.time;
        ++st.bounce;
        c.rays += 1;
        // The pending shadow ray's fields are written whether or not the lane has one
        // (only has_shadow says it is there), and a path that ends here takes the
        // next ray's fields too (nothing reads them after `done`): no branch on either,
        // which no predictor learns.
        const bool shadow = L.shadow[k] != 0;
        c.shadow_rays += shadow;
        c.rays += shadow;
        st.has_shadow = shadow;
        st.shadow = Ray(Vec3(L.sox[k], L.soy[k], L.soz[k]), Vec3(L.sdx[k], L.sdy[k], L.sdz[k]), 0.f, L.stfar[k]);
        st.shadow.time = time;
        st.shadow_light = light[k];
        st.shadow_delta = L.ls_delta[k] != 0;
        st.shadow_light_pdf = L.light_pdf[k];
        st.shadow_bsdf_pdf = L.shadow_bsdf_pdf[k];
        st.shadow_f = Spectrum(L.sf_r[k], L.sf_g[k], L.sf_b[k]);
        st.done = L.done[k] != 0;
        if (caustic && !st.done) {
            // PathTracer::scatter's camera side of r (these vertices are never Dirac): at
            // the first vertex 1 / (p_cam p(z1 -> z2)), later reverse over forward density
            const float nx = L.nsx[k], ny = L.nsy[k], nz = L.nsz[k];
            const float wx = L.rdx[k], wy = L.rdy[k], wz = L.rdz[k];
            const float cos_i = std::fabs(wx * nx + wy * ny + wz * nz);
            const float fwd = cos_i > 0.f ? L.pdf[k] / cos_i : 0.f;
            if (st.depth == 0) {
                const double den = double(caustic->camera_density(st.prev_p, Vec3(L.px[k], L.py[k], L.pz[k]),
                                                                  Vec3(L.ngx[k], L.ngy[k], L.ngz[k]))) *
                                   fwd;
                st.lt = den > 0.0 ? 1.0 / den : 0.0;
            } else if (st.lt > 0.0) {
                const Vec3 wo(L.wox[k], L.woy[k], L.woz[k]), wi(wx, wy, wz), ng(L.ngx[k], L.ngy[k], L.ngz[k]),
                    ns(nx, ny, nz);
                const float cos_o = std::fabs(dot(wo, ns));
                // Bsdf::pdf(wi, wo): preview_sample's, or the Lambertian's (consistent
                // sides, then |cos| / pi)
                float pdf_rev;
                if (preview) {
                    pdf_rev = L.pdf_rev[k];
                } else {
                    const float go = dot(wi, ng), gi = dot(wo, ng), lz = dot(wi, ns), iz = dot(wo, ns);
                    const bool cons = go != 0.f && gi != 0.f && (go * gi > 0.f) == (lz * iz > 0.f);
                    pdf_rev = cons && !(lz * iz <= 0.f) ? std::fabs(iz) * k_inv_pi : 0.f;
                }
                const float rev = cos_o > 0.f ? pdf_rev / cos_o : 0.f;
                st.lt = fwd > 0.f ? st.lt * double(rev) / double(fwd) : 0.0;
            }
        }
        const bool specular = preview && L.spec[k] != 0;
        st.beta = Spectrum(L.beta_r[k], L.beta_g[k], L.beta_b[k]);
        st.specular_bounce = false;
        st.prev_bsdf_pdf = L.pdf[k];
        st.prev_p = Vec3(L.px[k], L.py[k], L.pz[k]);
        st.ray = Ray(Vec3(L.rox[k], L.roy[k], L.roz[k]), Vec3(L.rdx[k], L.rdy[k], L.rdz[k]), 0.f, k_infinity);
        st.ray.time = time;
        st.diffuse_before_last = st.diffuse_seen;
        st.diffuse_seen = st.diffuse_seen || !specular;
        st.last_specular = specular;
        if (st.depth == 0) st.first_specular = specular;
        if (!specular && st.n_diffuse < 2) ++st.n_diffuse;
        ++st.depth;
    }
}

void PathBatch::trace_tile_to(const Tile& tile, uint32_t s, PathCounters& c, Film& film) {
    Spectrum L[k_tile_size * k_tile_size];
    float w[k_tile_size * k_tile_size];
    trace_tile(tile, s, c, L, w);
    const int tw = tile.x1 - tile.x0;
    for (int y = tile.y0; y < tile.y1; ++y)
        for (int x = tile.x0; x < tile.x1; ++x) {
            const int i = (y - tile.y0) * tw + (x - tile.x0);
            film.add_sample(x, y, s, L[i], w[i]);
        }
}

void PathBatch::trace_tile_to(const Tile& tile, uint32_t s, PathCounters& c, PassSplatter& splatter) {
    Spectrum L[k_tile_size * k_tile_size];
    float w[k_tile_size * k_tile_size];
    Vec2 p[k_tile_size * k_tile_size];
    trace_tile(tile, s, c, L, w, p);
    const int tw = tile.x1 - tile.x0;
    for (int y = tile.y0; y < tile.y1; ++y)
        for (int x = tile.x0; x < tile.x1; ++x) {
            const int i = (y - tile.y0) * tw + (x - tile.x0);
            splatter.set(x, y, p[i], L[i], s);
        }
}

void PathBatch::trace_tile(const Tile& tile, uint32_t s, PathCounters& c, Spectrum* L, float* w, Vec2* p) {
    const int tw = tile.x1 - tile.x0, th = tile.y1 - tile.y0;
    // Lanes: the tile's pixels in 4x4 blocks (camera rays of a packet are neighbours).
    m_live.clear();
    uint32_t lane = 0;
    for (int by = 0; by < th; by += 4)
        for (int bx = 0; bx < tw; bx += 4)
            for (int y = by; y < std::min(by + 4, th); ++y)
                for (int x = bx; x < std::min(bx + 4, tw); ++x) {
                    const uint32_t pixel =
                        PassSplatter::window_key(tile.x0 + x, tile.y0 + y, m_width, m_height, m_reach, m_shift);
                    m_pixel[lane] = uint32_t(y * tw + x);
                    m_sampler[lane] = PixelSampler(m_seed, pixel, s, RngStream::camera_path, m_tracer.sequence());
                    m_live.push_back(lane);
                    ++lane;
                }
    if (low_discrepancy(m_tracer.sequence())) {
        // the scramble seeds' part every dimension of a lane's sample shares (sobol.h)
        for (uint32_t l = 0; l < lane; ++l) m_c0[l] = m_sampler[l].pixel();
        sobol::seed_prefix_lanes(lane, m_c0.data(), sequence_seed_sample(m_tracer.sequence(), s),
                                 uint32_t(RngStream::camera_path), m_prefix.data());
    }
    // Camera rays (film position: dimension 0).
    prefetch_dimensions(m_live, 1, [](uint32_t) { return 0u; });
    if (m_use_lanes && m_pinhole_lanes) {
        // PathTracer::camera_ray: the film positions one lane at a time, the rays in lanes
        DiffuseLanes& L = *m_lanes;
        for (size_t k = 0; k < m_live.size(); ++k) {
            const uint32_t l = m_live[k], i = m_pixel[l];
            const int px = tile.x0 + int(i) % tw, py = tile.y0 + int(i) / tw;
            const Vec2 film = m_filter.film_position(px, py, m_sampler[l].get2d(), &w[i]);
            if (p) p[i] = film;
            L.film_x[k] = film.x;
            L.film_y[k] = film.y;
        }
        camera_directions(L, m_live.size(), m_pinhole);
        for (size_t k = 0; k < m_live.size(); ++k)
            m_tracer.begin(m_state[m_live[k]],
                           Ray(m_pinhole.origin, Vec3(L.dx[k], L.dy[k], L.dz[k]), L.ray_tnear[k], L.ray_tfar[k]), c);
    } else {
        for (uint32_t l : m_live) {
            const uint32_t i = m_pixel[l];
            const int px = tile.x0 + int(i) % tw, py = tile.y0 + int(i) / tw;
            float& weight = w[i];
            weight = 1.f;
            const Ray ray = m_tracer.camera_ray(m_camera, m_filter, m_motion_blur, m_sampler[l], m_seed, px, py,
                                                m_sampler[l].pixel(), s, &weight, p ? &p[i] : nullptr);
            m_tracer.begin(m_state[l], ray, c);
        }
    }

    const Accel& accel = m_scene.accel();
    while (!m_live.empty()) {
        // Closest hits of every live path.
        // With light proxies the one traversal also finds the analytic lights (Hit::light).
        const bool proxies = m_scene.light_proxies();
        for (uint32_t l : m_live) m_rays[l] = m_state[l].ray;
        m_packets += accel.intersect_lanes(m_rays.data(), m_live.data(), m_live.size(), m_hits.data(),
                                           m_packet_width, 4, proxies);
        // Shade: emission, the next ray, a pending shadow ray. A lane that scatters reads
        // the dimensions of its bounce (PathTracer::scatter): computed here, for every
        // lane that hit a mesh, at once (a miss or an analytic light ends the path).
        // (compacted without a branch: whether a path's ray hits is no pattern a
        // predictor learns)
        m_scattering.resize(m_live.size());
        m_ended.resize(m_live.size());
        size_t scattering = 0, ended = 0;
        for (uint32_t l : m_live) {
            const bool valid = m_hits[l].valid();
            m_scattering[scattering] = l;
            m_ended[ended] = l;
            scattering += valid;
            ended += !valid;
        }
        m_scattering.resize(scattering);
        m_ended.resize(ended);
        prefetch_dimensions(m_scattering, k_prefetch,
                            [&](uint32_t l) { return 1 + m_state[l].bounce * PathTracer::k_dims_per_bounce; });
        m_shadowed.clear();
        m_diffuse.clear();
        m_placed.clear();
        m_placed_preview.clear();
        m_placed_material.clear();
        m_placed_uv.clear();
        m_preview.clear();
        const bool lights = !proxies && m_scene.has_analytic_area_lights();
        const bool lanes = m_use_lanes;
        for (uint32_t l : m_scattering) {
            PathState& st = m_state[l];
            const Hit& h = m_hits[l];
            // The diffuse fast path: a mesh hit (no analytic light in front of it) on a
            // constant Lambertian, in the SoA lanes (static instances) or from the hit's
            // geometry; everything else through the full hit.
            uint32_t light;
            Spectrum le;
            if (!(lights && m_scene.nearest_light(m_rays[l], h.t, &light, &le) < k_infinity)) {
                if (lanes && gather_diffuse(l, c)) continue;
                HitGeometry g;
                m_scene.hit_geometry(m_rays[l], h, &g);
                if (const Spectrum* r = m_scene.constant_lambert(g.material_id)) {
                    m_tracer.step(st, LambertHit{&g, r}, m_sampler[l], c);
                } else {
                    m_tracer.step(st, m_scene.resolve_hit(m_rays[l], h), m_sampler[l], c);
                }
            } else {
                m_tracer.step(st, m_scene.resolve_hit(m_rays[l], h), m_sampler[l], c);
            }
        }
        // the misses and the light proxies' hits
        for (uint32_t l : m_ended) m_tracer.step(m_state[l], m_scene.resolve_hit(m_rays[l], m_hits[l]), m_sampler[l], c);
        if (!m_diffuse.empty() || !m_placed.empty() || !m_preview.empty()) shade_diffuse_lanes(c);
        // The lanes whose paths go on stay live, in their order, and those with a
        // pending shadow ray are listed (finishing a shadow ray never ends a path);
        // both compacted without a branch, as the hits above.
        size_t live = 0, pending = 0;
        m_pending.resize(m_live.size());
        for (uint32_t l : m_live) {
            const PathState& st = m_state[l];
            m_live[live] = l;
            live += !st.done;
            m_pending[pending] = l;
            pending += st.has_shadow;
        }
        for (size_t j = 0; j < pending; ++j) {
            const uint32_t l = m_pending[j];
            PathState& st = m_state[l];
            // Scene::transmittance, split around the BVH query: analytic lights first
            // (or in the query, as light proxies, each skipping its target's own).
            if (proxies) {
                m_skip_light[l] = m_scene.shadow_skip_proxy(st.shadow_light);
            } else if (m_scene.blocked_by_light(st.shadow, st.shadow_light)) {
                PathTracer::finish_shadow(st, 0.f, 1.f);
                continue;
            }
            m_rays[l] = st.shadow;
            m_shadowed.push_back(l);
        }
        // Visibility of the shadow rays.
        m_packets += accel.occluded_lanes(m_rays.data(), m_shadowed.data(), m_shadowed.size(), m_occluded.data(),
                                          m_packet_width, 4, proxies, proxies ? m_skip_light.data() : nullptr);
        if (!m_scene.has_pass_through()) {
            // nothing lets a ray through: unoccluded or not, without a branch
            for (uint32_t l : m_shadowed) PathTracer::finish_shadow_visible(m_state[l], m_occluded[l] == 0);
        } else {
            for (uint32_t l : m_shadowed) {
                float pass_pdf = 1.f;
                const PathState& st = m_state[l];
                const float tr = proxies ? m_scene.transmittance_given_lights(m_rays[l], st.shadow_light,
                                                                              m_occluded[l] != 0, &pass_pdf)
                                         : m_scene.transmittance_given(m_rays[l], m_occluded[l] != 0, &pass_pdf);
                PathTracer::finish_shadow(m_state[l], tr, pass_pdf);
            }
        }
        m_live.resize(live);
    }
    for (uint32_t l = 0; l < lane; ++l) L[m_pixel[l]] = m_state[l].L;
}

}  // namespace cmlt
