// The frame of the Metropolis integrators; see mlt_frame.h.
#include "integrators/mlt/mlt_frame.h"

#include "integrators/mlt/mlt_sampler.h"
#include "integrators/mlt/pssmlt_tracer.h"
#include "integrators/path/path_tracer_impl.h"
#include "sampling/rng_domains.h"
#include "scene/scene.h"
#include "util/error.h"

#include <algorithm>
#include <cmath>

namespace cmlt::mlt {

FrameBudget FrameBudget::plan(const RenderSettings& s, uint64_t bootstrap) {
    FrameBudget b;
    b.pilot = MltContext::pilot_cost(s);
    b.direct = MltContext::direct_cost(s);  // a sample budget's; timed: as it runs
    if (!MltContext::chains_needed(s)) return b;  // max_depth 1 with a direct pass
    const uint64_t left = MltContext::evaluation_budget(s);
    // auto with given values: the driver sized them (bootstrap_size); a set size must match
    const uint64_t wanted =
        s.mlt_bootstrap_f && s.bootstrap_samples == 0 ? uint64_t(s.mlt_bootstrap_f->size()) : bootstrap;
    b.bootstrap = std::max<uint64_t>(1, std::min<uint64_t>(wanted, left / 2));
    b.chains = left - b.bootstrap;
    return b;
}

FrameBudget FrameBudget::plan(const RenderSettings& s) {
    return plan(s, s.bootstrap_samples > 0 ? uint64_t(s.bootstrap_samples) : k_bootstrap_default);
}

namespace {

/// Of k_bootstrap_probe samples keyed (seed, bootstrap_probe, i), those with f* > 0;
/// `seconds`: the probe's time.
uint64_t count_probe(const RenderSettings& s, const PssmltTracer& tracer, tbb::task_arena& arena,
                     FrameCounters& counters, double* seconds) {
    const uint64_t n = k_bootstrap_probe;
    std::vector<uint8_t> carries(n, 0);
    const auto start = std::chrono::steady_clock::now();
    parallel_tasks(arena, counters, n, uint64_t(256), [&](const tbb::blocked_range<uint64_t>& r) {
        PathCounters c;
        uint64_t bad = 0;
        for (uint64_t i = r.begin(); i != r.end(); ++i) {
            MltSampler smp(s.seed, s.sigma, s.large_step_probability, RngDomain::bootstrap_probe, uint32_t(i));
            smp.start_iteration(true);
            const PathSample x = tracer.evaluate(smp, c);
            bad += x.invalid ? 1 : 0;
            carries[i] = !x.invalid && x.f > 0.0;
        }
        counters.add(c, bad);
    });
    *seconds = seconds_since(start);
    uint64_t nonzero = 0;
    for (uint8_t v : carries) nonzero += v;
    return nonzero;
}

/// The auto bootstrap size's cap: k_bootstrap_share of the evaluations left for bootstrap
/// and chains.
uint64_t bootstrap_cap(const RenderSettings& s) {
    return uint64_t(k_bootstrap_share * double(MltContext::evaluation_budget(s)));
}

/// bootstrap_size's wanted size from a probe's count (the cap above and, with a time
/// budget, k_bootstrap_share of the seconds at the probe's rate).
uint64_t wanted_from_probe(const RenderSettings& s, uint64_t nonzero, double seconds) {
    uint64_t cap = bootstrap_cap(s);
    const uint64_t n = k_bootstrap_probe;
    if (s.time_budget > 0.0 && seconds > 0.0)
        cap = std::min<uint64_t>(cap, uint64_t(k_bootstrap_share * s.time_budget * double(n) / seconds));
    // about one sample that carries light per chain (none seen: as if one had been)
    const double want =
        std::ceil(double(std::max(s.chains, 1)) * double(n) / double(std::max<uint64_t>(nonzero, 1)));
    return std::max(k_bootstrap_default, std::min<uint64_t>(cap, uint64_t(std::min(want, 1e15))));
}

}  // namespace

BootstrapSize bootstrap_size(const RenderSettings& s, const PssmltTracer& tracer, tbb::task_arena& arena,
                             FrameCounters& counters) {
    BootstrapSize out;
    if (s.bootstrap_samples > 0) {
        out.wanted = uint64_t(s.bootstrap_samples);
        return out;
    }
    out.wanted = k_bootstrap_default;
    // given values (the temporal driver sized them), no chains, or no room to grow: no probe
    if (s.mlt_bootstrap_f || !MltContext::chains_needed(s)) return out;
    if (bootstrap_cap(s) <= k_bootstrap_default) return out;
    double seconds = 0.0;
    out.probe = k_bootstrap_probe;
    out.probe_nonzero = count_probe(s, tracer, arena, counters, &seconds);
    out.wanted = wanted_from_probe(s, out.probe_nonzero, seconds);
    return out;
}

bool start_probe_applies(const Scene& scene, const RenderSettings& given) {
    if (given.integrator != "pssmlt" && given.integrator != "cmlt") return false;
    if (given.mlt_min_starts <= 0 || given.mlt_paths != "auto" || given.bootstrap_samples != 0) return false;
    if (given.mlt_bootstrap_f || given.mlt_initial_states) return false;  // the temporal driver's frame
    const RenderSettings resolved = MltContext::resolve_paths(scene, given);
    return resolved.mlt_paths == "caustics" && MltContext::chains_needed(resolved);
}

StartProbe probe_starts(const Scene& scene, const RenderSettings& given) {
    StartProbe out;
    const RenderSettings s = MltContext::resolve_paths(scene, given);
    // the probe's tracer without the pixel importance (f* > 0 either way; no pilot image
    // to render); the budget below is the frame's, its pilot's cost included
    RenderSettings luminance = s;
    luminance.importance = "luminance";
    PathCounters pilot;  // (none rendered)
    const MltContext ctx(scene, luminance, pilot);
    tbb::task_arena arena(frame_threads(s));
    double seconds = 0.0;
    out.probe = k_bootstrap_probe;
    FrameCounters counters;
    out.nonzero = count_probe(s, ctx.tracer, arena, counters, &seconds);
    out.counters = counters.paths();
    // the bootstrap the frame would take (bootstrap_size: no probe where the cap is the
    // default's), and the share of it the probe saw carry light
    const uint64_t wanted =
        bootstrap_cap(s) <= k_bootstrap_default ? k_bootstrap_default : wanted_from_probe(s, out.nonzero, seconds);
    out.bootstrap = FrameBudget::plan(s, wanted).bootstrap;
    out.expected = double(out.nonzero) * double(out.bootstrap) / double(out.probe);
    out.too_few = out.expected < double(given.mlt_min_starts);
    return out;
}

MltFrame::MltFrame(const Scene& scene_, const RenderSettings& s)
    : scene(scene_), settings(s), threads(frame_threads(s)), arena(threads), t0(std::chrono::steady_clock::now()),
      ctx(scene_, s, m_pilot_counters), direct_pass(scene_, s),
      bootstrap_size(mlt::bootstrap_size(s, ctx.tracer, arena, counters)),
      budget(FrameBudget::plan(s, bootstrap_size.wanted)), film(s.width, s.height, error_layers(s)),
      direct{direct_pass, s, arena, counters} {
    counters.add(m_pilot_counters);
}

namespace {

void develop_image(RenderResult& res, const SplatFilm& film, double b, uint64_t steps, const PtPassImage& direct) {
    const size_t pixels = size_t(res.width) * size_t(res.height);
    res.image.assign(pixels * 3, 0.f);
    res.variance.assign(pixels * 3, 0.f);
    const double scale = steps > 0 ? b * double(pixels) / double(steps) : 0.0;
    for (size_t i = 0; i < pixels; ++i)
        for (int k = 0; k < 3; ++k) {
            const double chain = scale * film.sum(i, k);
            const double d = direct.mean.empty() ? 0.0 : double(direct.mean[3 * i + k]);
            res.image[3 * i + k] = float(chain + d);
        }
    if (!direct.mean.empty()) {
        res.direct = direct.mean;
        res.variance = direct.variance;
        res.robust = direct.robust;
    }
}

}  // namespace

ErrorValue estimate_groups(const SplatFilm& film, const std::vector<double>& steps,
                           const mcmc::NormalisationEstimate& b, const PtPassImage& direct,
                           std::vector<float>* group_images, std::vector<double>* used_steps) {
    const int G = film.layers();
    if (G < 3 || int(steps.size()) != G || !(b.mean > 0.0)) return ErrorValue{};
    const size_t pixels = size_t(film.width()) * size_t(film.height()), n = pixels * 3;
    double total = 0.0;
    std::vector<int> used;  // the layers with steps (an empty group has no image)
    std::vector<double> weights, scale;
    for (int g = 0; g < G; ++g) {
        total += steps[size_t(g)];
        if (!(steps[size_t(g)] > 0.0)) continue;
        used.push_back(g);
        weights.push_back(steps[size_t(g)]);
        scale.push_back(b.mean * double(pixels) / steps[size_t(g)]);
    }
    if (used.size() < 3 || total <= 0.0) return ErrorValue{};
    const double s_all = b.mean * double(pixels) / total;
    const double b_rel_var = b.std_error > 0.0 ? (b.std_error / b.mean) * (b.std_error / b.mean) : 0.0;
    const bool has_direct = !direct.mean.empty();
    auto group = [&](size_t g, size_t i) {
        return scale[g] * film.layer_sum(used[g], i / 3, int(i % 3)) + (has_direct ? double(direct.mean[i]) : 0.0);
    };
    auto shared = [&](size_t i) {
        const double c = s_all * film.sum(i / 3, int(i % 3));
        return (has_direct ? double(direct.variance[i]) : 0.0) + b_rel_var * c * c;
    };
    if (group_images) {
        group_images->resize(used.size() * n);
        for (size_t g = 0; g < used.size(); ++g)
            for (size_t i = 0; i < n; ++i) (*group_images)[g * n + i] = float(group(g, i));
    }
    if (used_steps) *used_steps = weights;
    return estimate_from_groups(n, weights, group, shared);
}

bool target_round(ErrorTarget& t, ChainSchedule& schedule, const ErrorValue& e, double work, uint64_t evaluations,
                  uint64_t chain_budget, int groups) {
    const int done = schedule.round() + 1;  // rounds run
    const bool reached = t.reached(work, schedule.elapsed(), e) && done >= 2 * groups;
    if (reached || chain_budget == 0) return reached;
    const double f = double(evaluations) / double(chain_budget);
    // the first 2G rounds grow linearly (equal slices), then as the target predicts
    schedule.set_fraction(done < 2 * groups ? f * double(done + 1) / double(done) : t.next_work(f));
    return false;
}

RenderResult MltFrame::finish(PopulationResult&& chains) {
    const PtPassImage direct_image = direct_pass.develop(true);
    const double secs = seconds_since(t0);

    RenderResult res;
    res.width = settings.width;
    res.height = settings.height;
    develop_image(res, film, chains.b.mean, chains.steps, direct_image);
    res.cancelled = chains.cancelled;
    if (chains.direct_alone) {  // the direct pass's own estimate (as pt's)
        if (!direct_image.mean.empty()) {
            const ErrorValue err = estimate_from_variance(direct_image.mean.data(), direct_image.variance.data(),
                                                          direct_image.robust.data(),
                                                          settings.width, settings.height);
            res.error_estimate = err.relmse;
            res.error_stderr = err.stderr_;
        }
    } else if (film.layers() >= 3) {
        std::vector<double> used_steps;
        const ErrorValue err =
            estimate_groups(film, chains.group_steps, chains.b, direct_image, &res.group_images, &used_steps);
        res.error_estimate = err.relmse;
        res.error_stderr = err.stderr_;
        if (err.valid()) res.group_weights = std::move(used_steps);
        else res.group_images.clear();
    }
    res.error_history = std::move(chains.error_history);
    res.stop_reason = stop_reason(chains.cancelled, chains.target_reached, settings.time_budget > 0.0, secs,
                                  settings.time_budget);
    res.bootstrap_f.assign(chains.bootstrap_f.begin(), chains.bootstrap_f.end());
    res.mlt_states = std::move(chains.states);
    res.mlt_start_states = std::move(chains.start_states);

    RenderStats& st = res.stats;
    fill_frame_stats(st, counters, rate, secs);
    st.nan_samples = counters.invalid.load() + chains.invalid + direct_image.nan_samples;
    st.threads = threads;
    st.integrator = settings.integrator;
    st.spp = settings.spp;
    st.seed = settings.seed;

    MltStats& m = st.mlt;
    m.enabled = true;
    m.b = chains.b.mean;
    m.b_stderr = chains.b.std_error;
    m.b_bootstrap = chains.b_bootstrap.mean;
    m.b_bootstrap_stderr = chains.b_bootstrap.std_error;
    m.bootstrap_samples = budget.bootstrap;
    m.bootstrap_nonzero = chains.b_bootstrap.nonzero;
    m.bootstrap_probe = bootstrap_size.probe;
    m.bootstrap_probe_nonzero = bootstrap_size.probe_nonzero;
    m.sigma = settings.sigma;
    m.max_rejection_streak = chains.streaks.max_streak;
    m.long_streak_rejections = chains.streaks.long_streak_rejections;
    m.states_visited = chains.streaks.occupancy.states();
    m.top_occupancy = chains.streaks.occupancy.top_fraction(0.001);
    m.stuck_chains = chains.shares.stuck();
    m.max_chain_share = chains.shares.max_share();
    m.max_stay_share = chains.shares.max_stay_share();
    m.path_sampler = settings.mlt_path_sampler;
    m.importance = settings.importance;
    m.pilot_evaluations = budget.pilot;
    m.direct_evaluations = direct_pass.evaluations();
    m.direct_alone = chains.direct_alone;
    st.lens_lights = direct_pass.lens_lights();
    st.caustic_casters = direct_pass.caustic_casters();
    m.min_depth = MltContext::min_depth(settings);
    m.camera_technique = ctx.tracer.technique().camera_probability();
    st.emission_guiding = settings.mlt_path_sampler == "bdpt" ? ctx.bdpt.emission_guiding() : 0.0;
    st.caster_coverage = ctx.caster_coverage;
    m.paths = settings.mlt_paths;
    m.time_budget = settings.time_budget;
    m.chains = chains.chains;
    m.mutations = chains.steps;
    m.mutations_per_pixel = double(chains.steps) / double(uint64_t(settings.width) * uint64_t(settings.height));
    m.large_steps = chains.kernel[mcmc::MutationKind::large_step].steps;
    m.acceptance_large = chains.kernel[mcmc::MutationKind::large_step].acceptance_rate();
    m.imported_chains = chains.imported ? chains.chains : 0;
    m.clamped_splats = film.clamped();
    m.path_evaluations =
        budget.pilot + direct_pass.evaluations() + bootstrap_size.probe + budget.bootstrap + chains.evaluations;
    if (settings.partial) {
        // a part of the frame: its raw sums, which combine_parts adds up exactly
        auto part = std::make_shared<MltPart>();
        film.export_words(part->splat_lo, part->splat_hi);
        const size_t n = chains.part_norms.size();
        part->norm_counts.resize(2 * n);
        part->norm_moments.resize(2 * n);
        for (size_t i = 0; i < n; ++i) chains.part_norms[i].raw(&part->norm_counts[2 * i], &part->norm_moments[2 * i]);
        if (n == 0) {  // no chains ran (none needed): an empty bootstrap accumulator
            part->norm_counts.assign(2, 0);
            part->norm_moments.assign(2, 0.0);
        }
        part->steps = chains.steps;
        res.mlt_part = std::move(part);
    }
    return res;
}

RenderResult combine_parts(int width, int height, const std::vector<const MltPart*>& parts,
                           const std::vector<float>& direct) {
    const size_t n = size_t(width) * size_t(height) * 3;
    if (parts.empty()) throw SettingsError("combine_mlt_parts: no parts");
    if (!direct.empty() && direct.size() != n)
        CMLT_THROW(SettingsError, "combine_mlt_parts: the direct image has " << direct.size()
                                      << " values, the frame " << n);
    SplatFilm film(width, height);
    mcmc::NormalisationAccumulator b_acc;
    uint64_t steps = 0;
    for (size_t p = 0; p < parts.size(); ++p) {
        const MltPart& part = *parts[p];
        if (part.splat_lo.size() != n || part.splat_hi.size() != n || part.norm_counts.size() < 2 ||
            part.norm_counts.size() != part.norm_moments.size())
            CMLT_THROW(SettingsError, "combine_mlt_parts: part " << p << " is not a part of a "
                                          << width << " x " << height << " frame");
        film.add_words(part.splat_lo.data(), part.splat_hi.data());
        // the bootstrap (the same in every part) once, then the chains in chain order,
        // as the single-process frame merges them
        for (size_t i = p == 0 ? 0 : 1; i < part.norm_counts.size() / 2; ++i)
            b_acc.merge(mcmc::NormalisationAccumulator::from_raw(&part.norm_counts[2 * i], &part.norm_moments[2 * i]));
        steps += part.steps;
    }
    const mcmc::NormalisationEstimate b = b_acc.estimate();
    RenderResult res;
    res.width = width;
    res.height = height;
    PtPassImage d;
    d.mean = direct;
    develop_image(res, film, b.mean, steps, d);
    res.stats.mlt.enabled = true;
    res.stats.mlt.b = b.mean;
    res.stats.mlt.b_stderr = b.std_error;
    res.stats.mlt.mutations = steps;
    res.stats.mlt.clamped_splats = film.clamped();
    return res;
}

}  // namespace cmlt::mlt
