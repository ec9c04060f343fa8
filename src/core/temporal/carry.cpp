// Carrying chain populations across frames; see carry.h.
#include "temporal/carry.h"

#include "cameras/camera.h"
#include "integrators/bdpt/bdpt_tracer.h"
#include "integrators/mlt/mlt_context.h"
#include "integrators/mlt/mlt_frame.h"
#include "integrators/mlt/mlt_sampler.h"
#include "integrators/mlt/pssmlt_tracer.h"
#include "integrators/path/path_tracer_impl.h"
#include "sampling/rng.h"
#include "sampling/rng_domains.h"
#include "scene/scene.h"
#include "util/error.h"
#include "util/fp_mode.h"

#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <mutex>

namespace cmlt::temporal {

namespace {

using mlt::MltSampler;

/// The path samplers of one frame, built as the renders build them (mlt_context.h), so
/// f* here is f* there.
struct Tracers {
    Tracers(const Scene& scene, const RenderSettings& s) : ctx(scene, s, pilot_counters), tracer(ctx.tracer) {}
    PathCounters pilot_counters;
    mlt::MltContext ctx;
    const mlt::PssmltTracer& tracer;
};

void fill_state(mlt::ChainState& out, const MltSampler& smp, const mlt::PathSample& x) {
    const auto u = smp.current_state();
    for (size_t k = 0; k < u.size(); ++k) {
        out.u[k].resize(u[k].size());
        for (size_t i = 0; i < u[k].size(); ++i)
            out.u[k][i] = std::isnan(u[k][i]) ? std::numeric_limits<float>::quiet_NaN()
                                              : unit_float(u[k][i]);  // never 1 (would import as "no value")
    }
    out.depth = x.depth >= 0 ? uint32_t(x.depth) : 0u;
    out.s = x.s >= 0 ? uint32_t(x.s) : 0u;
    out.t = x.t >= 0 ? uint32_t(x.t) : 0u;
    out.f_star = x.f;
    out.colour = x.L;
}

template <class Fn>
void parallel(const RenderSettings& s, uint64_t n, Fn&& fn, PathCounters* total = nullptr) {
    const int threads = s.threads > 0 ? s.threads : tbb::info::default_concurrency();
    tbb::task_arena arena(threads);
    std::mutex mutex;
    arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n, 16), [&](const tbb::blocked_range<uint64_t>& r) {
            ScopedFtzDaz ftz;  // as the render's chains: the same f* bit for bit
            PathCounters c;
            for (uint64_t i = r.begin(); i != r.end(); ++i) fn(i, c);
            if (!total) return;
            const std::lock_guard<std::mutex> lock(mutex);
            total->camera_rays += c.camera_rays;
            total->shadow_rays += c.shadow_rays;
            total->rays += c.rays;
            total->samples += c.samples;
        });
    });
}

void check_settings(const RenderSettings& s, const char* fn) {
    if (s.width < 1 || s.height < 1)
        CMLT_THROW(SettingsError, fn << ": resolution " << s.width << "x" << s.height << " is empty");
    if (s.mlt_path_sampler != "bdpt" && s.mlt_path_sampler != "pt")
        CMLT_THROW(SettingsError, fn << ": unknown path sampler '" << s.mlt_path_sampler << "'");
}

}  // namespace

std::shared_ptr<mlt::ChainStates> evaluate_states(const Scene& scene, const RenderSettings& settings,
                                                  const mlt::ChainStates& states) {
    check_settings(settings, "evaluate_states");
    if (states.path_sampler != settings.mlt_path_sampler)
        CMLT_THROW(SettingsError, "evaluate_states: states of the '" << states.path_sampler
                                      << "' path sampler cannot be evaluated with '"
                                      << settings.mlt_path_sampler << "'");
    const RenderSettings resolved = mlt::MltContext::resolve_paths(scene, settings);
    const Tracers tr(scene, resolved);
    auto out = std::make_shared<mlt::ChainStates>();
    out->path_sampler = states.path_sampler;
    out->chains.resize(states.chains.size());
    parallel(settings, states.chains.size(), [&](uint64_t i, PathCounters& c) {
        const mlt::ChainState& in = states.chains[i];
        MltSampler smp(settings.seed, settings.sigma, settings.large_step_probability,
                       RngDomain::carry_evaluate, uint32_t(i));
        smp.import_state(in.u);
        smp.begin_replay();
        const mlt::PathSample x = tr.tracer.evaluate(smp, c);
        smp.end_replay();
        mlt::ChainState& o = out->chains[i];
        o.chain_id = in.chain_id;
        fill_state(o, smp, x);
    });
    return out;
}

uint64_t bootstrap_count(const RenderSettings& settings) {
    return mlt::FrameBudget::plan(settings).bootstrap;
}

uint64_t chain_count(const RenderSettings& settings) {
    const uint64_t n_mut = mlt::FrameBudget::plan(settings).chains;
    const uint64_t asked = uint64_t(std::max(settings.chains, 1));
    if (settings.integrator == "pssmlt") return std::min(asked, n_mut);
    if (settings.integrator == "cmlt") {
        if (n_mut == 0) return 0;
        const uint64_t block = 1 + uint64_t(settings.inner_length) * uint64_t(settings.tries);
        return std::min(asked, std::max<uint64_t>(1, n_mut / block));
    }
    return 0;
}

std::shared_ptr<mlt::ChainStates> bootstrap_states(const Scene& scene, const RenderSettings& settings,
                                                   uint64_t count, PathCounters* counters, uint64_t* probe,
                                                   uint64_t* probe_nonzero) {
    check_settings(settings, "bootstrap_states");
    const RenderSettings resolved = mlt::MltContext::resolve_paths(scene, settings);
    const Tracers tr(scene, resolved);
    if (count == 0) {
        tbb::task_arena arena(settings.threads > 0 ? settings.threads : tbb::info::default_concurrency());
        FrameCounters probe_counters;
        RenderSettings unsized = resolved;
        unsized.mlt_bootstrap_f = nullptr;
        const mlt::BootstrapSize size = mlt::bootstrap_size(unsized, tr.tracer, arena, probe_counters);
        count = mlt::FrameBudget::plan(unsized, size.wanted).bootstrap;
        if (probe) *probe = size.probe;
        if (probe_nonzero) *probe_nonzero = size.probe_nonzero;
        if (counters) {
            counters->rays += probe_counters.rays.load();
            counters->camera_rays += probe_counters.camera_rays.load();
            counters->shadow_rays += probe_counters.shadow_rays.load();
        }
    }
    auto out = std::make_shared<mlt::ChainStates>();
    out->path_sampler = settings.mlt_path_sampler;
    out->chains.resize(size_t(count));
    parallel(settings, count, [&](uint64_t i, PathCounters& c) {
        // as the render's bootstrap (pssmlt_integrator.cpp; cmlt's keys (bootstrap, i, 1)
        // are the same point): one large step of the sampler keyed (bootstrap, i)
        MltSampler smp(settings.seed, settings.sigma, settings.large_step_probability, RngDomain::bootstrap,
                       uint32_t(i));
        smp.start_iteration(true);
        const mlt::PathSample x = tr.tracer.evaluate(smp, c);
        smp.accept();
        mlt::ChainState& o = out->chains[size_t(i)];
        o.chain_id = i;
        fill_state(o, smp, x);
        o.f_star = x.invalid ? 0.0 : x.f;
    }, counters);
    return out;
}

double keyed_uniform(uint64_t seed, uint32_t domain, uint32_t id, uint32_t counter) {
    const Philox4x32Counter r =
        philox4x32(metropolis_counter(RngTag::keyed, RngDomain(domain), id, counter, 0), seed_key(seed));
    return bits_to_unit(r[0], r[1]);
}

CoupledStarts couple_starts(const std::vector<double>& f_old, const std::vector<double>& f_new,
                            const std::vector<uint64_t>& prev_picks, uint64_t n, uint64_t seed,
                            uint32_t frame_key) {
    const auto clean = [](double v) { return (std::isfinite(v) && v > 0.0) ? v : 0.0; };
    double sum_new = 0.0, sum_old = 0.0;
    for (double v : f_new) sum_new += clean(v);
    for (double v : f_old) sum_old += clean(v);
    CoupledStarts out;
    if (!(sum_new > 0.0) || n == 0) return out;  // nothing to start from
    const bool coupled = !prev_picks.empty() && f_old.size() == f_new.size() && sum_old > 0.0;
    std::vector<int64_t> slot(size_t(n), -1);   // the chain's bootstrap index, -1: to draw
    std::vector<uint8_t> residual(size_t(n), 0);  // 1: refreshed from the residual, 0: fresh
    if (coupled) {
        double tv = 0.0;
        for (size_t i = 0; i < f_new.size(); ++i) tv += std::max(0.0, clean(f_new[i]) / sum_new - clean(f_old[i]) / sum_old);
        out.tv = tv;
        for (uint64_t k = 0; k < n; ++k) {
            if (k >= prev_picks.size() || prev_picks[size_t(k)] >= f_new.size()) continue;  // fresh
            const size_t i = size_t(prev_picks[size_t(k)]);
            const double p = clean(f_old[i]) / sum_old, q = clean(f_new[i]) / sum_new;
            // keep with probability min(1, q/p); p = 0 cannot have been picked (a
            // start from a state file written with other values: refresh it)
            const double a = p > 0.0 ? std::min(1.0, q / p) : 0.0;
            if (a >= 1.0 || keyed_uniform(seed, uint32_t(RngDomain::carry_keep), uint32_t(k), frame_key) < a) {
                slot[size_t(k)] = int64_t(i);
                ++out.kept;
            } else {
                residual[size_t(k)] = 1;
            }
        }
    }
    // the draws: refreshed chains from the residual (q − p)^+, new chains from q; each group
    // by systematic resampling with a keyed uniform, assigned in chain order
    for (int group = 1; group >= 0; --group) {
        std::vector<uint64_t> who;
        for (uint64_t k = 0; k < n; ++k)
            if (slot[size_t(k)] < 0 && residual[size_t(k)] == uint8_t(group)) who.push_back(k);
        if (who.empty()) continue;
        std::vector<double> w(f_new.size());
        double total = 0.0;
        for (size_t i = 0; i < f_new.size(); ++i) {
            const double q = clean(f_new[i]) / sum_new;
            w[i] = group == 1 ? std::max(0.0, q - clean(f_old[i]) / sum_old) : q;
            total += w[i];
        }
        if (!(total > 0.0)) {  // rounding left no residual mass: draw from q
            for (size_t i = 0; i < f_new.size(); ++i) w[i] = clean(f_new[i]) / sum_new;
        }
        const double u0 = keyed_uniform(seed, uint32_t(RngDomain::carry_refresh), uint32_t(group), frame_key);
        const std::vector<uint64_t> picks = systematic_resample(w, who.size(), u0);
        for (size_t j = 0; j < who.size() && j < picks.size(); ++j) slot[size_t(who[j])] = int64_t(picks[j]);
        (group == 1 ? out.refreshed : out.fresh) += who.size();
    }
    out.picks.reserve(size_t(n));
    for (int64_t s : slot) out.picks.push_back(uint64_t(s));
    return out;
}

std::vector<Anchor> screen_anchors(const Scene& scene, const RenderSettings& settings, int n_x, int n_y) {
    check_settings(settings, "screen_anchors");
    if (n_x < 1 || n_y < 1) CMLT_THROW(SettingsError, "screen_anchors: grid " << n_x << "x" << n_y << " is empty");
    const Camera camera(scene.camera_desc(), settings.width, settings.height);
    std::vector<Anchor> out(size_t(n_x) * size_t(n_y));
    parallel(settings, out.size(), [&](uint64_t i, PathCounters&) {
        Anchor& a = out[size_t(i)];
        const int gx = int(i % uint64_t(n_x)), gy = int(i / uint64_t(n_x));
        a.p_raster = Vec2((float(gx) + 0.5f) * float(settings.width) / float(n_x),
                          (float(gy) + 0.5f) * float(settings.height) / float(n_y));
        Ray ray = camera.generate_ray(a.p_raster);
        const SceneHit h = scene.intersect(ray);
        if (h.kind != SceneHit::Kind::surface) return;
        const Instance& inst = scene.instance(h.si.instance_id);
        a.instance = int32_t(h.si.instance_id);
        a.p_object = inst.matrix_at(h.si.time).inverse().transform_point(h.si.p);
    });
    return out;
}

std::vector<Vec2> project_anchors(const Scene& scene, const RenderSettings& settings,
                                  const std::vector<Anchor>& anchors) {
    check_settings(settings, "project_anchors");
    const Camera camera(scene.camera_desc(), settings.width, settings.height);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    std::vector<Vec2> out(anchors.size(), Vec2(nan, nan));
    for (size_t i = 0; i < anchors.size(); ++i) {
        const Anchor& a = anchors[i];
        if (a.instance < 0 || size_t(a.instance) >= scene.instance_count()) continue;
        const Vec3 p = scene.instance(uint32_t(a.instance)).matrix_at(0.f).transform_point(a.p_object);
        Vec2 r;
        if (camera.world_to_raster(p, &r) && std::isfinite(r.x) && std::isfinite(r.y)) out[i] = r;
    }
    return out;
}

std::vector<uint64_t> systematic_resample(const std::vector<double>& weights, uint64_t n, double u0) {
    double total = 0.0;
    for (double w : weights) total += (std::isfinite(w) && w > 0.0) ? w : 0.0;
    std::vector<uint64_t> out;
    if (!(total > 0.0) || n == 0) return out;
    out.reserve(size_t(n));
    const double step = total / double(n);
    double next = u0 * step, cum = 0.0;
    size_t i = 0;
    for (uint64_t k = 0; k < n; ++k, next = (u0 + double(k)) * step) {
        // the index whose cumulative interval [cum, cum + w_i) holds `next`
        while (i < weights.size()) {
            const double w = (std::isfinite(weights[i]) && weights[i] > 0.0) ? weights[i] : 0.0;
            if (w > 0.0 && next < cum + w) break;
            cum += w;
            ++i;
        }
        if (i == weights.size()) {  // rounding at the top end: the last positive weight
            size_t j = weights.size();
            while (j > 0 && !(std::isfinite(weights[j - 1]) && weights[j - 1] > 0.0)) --j;
            out.push_back(uint64_t(j - 1));
            continue;
        }
        out.push_back(uint64_t(i));
    }
    return out;
}

RatioStats ratio_statistics(const std::vector<double>& f_old, const std::vector<double>& f_new) {
    CMLT_CHECK_MSG(f_old.size() == f_new.size(), "ratio_statistics: size mismatch");
    RatioStats r;
    double mean = 0.0, m2 = 0.0;  // Welford, in index order
    for (size_t i = 0; i < f_old.size(); ++i) {
        if (!(f_old[i] > 0.0) || !std::isfinite(f_old[i])) continue;
        const double w = std::isfinite(f_new[i]) && f_new[i] > 0.0 ? f_new[i] / f_old[i] : 0.0;
        if (w == 0.0) ++r.zero;
        ++r.count;
        const double d = w - mean;
        mean += d / double(r.count);
        m2 += d * (w - mean);
    }
    r.mean = mean;
    r.variance = r.count > 1 ? m2 / double(r.count - 1) : 0.0;
    return r;
}

std::shared_ptr<mlt::ChainStates> gather_states(const mlt::ChainStates& a, const mlt::ChainStates& b,
                                                const std::vector<uint64_t>& picks, uint64_t pool_id_base) {
    auto out = std::make_shared<mlt::ChainStates>();
    out->path_sampler = a.chains.empty() ? b.path_sampler : a.path_sampler;
    out->chains.reserve(picks.size());
    for (uint64_t p : picks) {
        if (p < a.chains.size()) {
            out->chains.push_back(a.chains[size_t(p)]);
        } else {
            const uint64_t j = p - a.chains.size();
            CMLT_CHECK_MSG(j < b.chains.size(), "gather_states: pick " << p << " out of range");
            out->chains.push_back(b.chains[size_t(j)]);
            out->chains.back().chain_id = pool_id_base + j;
        }
    }
    return out;
}

}  // namespace cmlt::temporal
