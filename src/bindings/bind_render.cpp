// Bindings of render() and its results: the GIL is released while rendering and
// re-acquired only to call the progress callback (from the calling thread).
// RenderSettings and the settings table: bind_settings.cpp.
#include "bind_common.h"

#include "integrators/aov/aov_pass.h"
#include "integrators/common/render.h"
#include "integrators/mlt/chain_state.h"
#include "integrators/mlt/mlt_context.h"
#include "integrators/mlt/mlt_frame.h"
#include "integrators/mlt/direct_pass.h"
#include "integrators/mlt/pixel_importance.h"
#include "integrators/path/path_tracer.h"
#include "scene/scene.h"
#include "util/error.h"

#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <exception>
#include <sstream>

namespace cmlt::bindings {

using namespace nb::literals;

nb::object rgb_to_numpy(std::vector<float>&& v, int h, int w) {
    auto* heap = new std::vector<float>(std::move(v));
    nb::capsule owner(heap, [](void* p) noexcept { delete static_cast<std::vector<float>*>(p); });
    size_t shape[3] = {size_t(h), size_t(w), 3};
    return nb::ndarray<nb::numpy, float>(heap->data(), 3, shape, owner).cast();
}

namespace {

struct PyRenderResult {
    nb::object image, variance, robust;
    nb::object direct;  ///< None unless an MLT render had a direct pass
    nb::object bootstrap_f;  ///< float32 (N,) for pssmlt / cmlt, else None
    bool cancelled = false;
    nb::object group_images;   ///< float32 (G, H, W, 3) of the error groups, else None
    nb::object group_weights;  ///< their image normalisation counts (list), else None
    nb::dict stats;
    std::shared_ptr<mlt::ChainStates> mlt_states;  ///< pssmlt / cmlt, else None
    std::shared_ptr<mlt::ChainStates> mlt_start_states;
    nb::object mlt_part;  ///< dict of numpy arrays with RenderSettings.partial, else None
};

template <class T>
nb::object vec_to_numpy(std::vector<T>&& v) {
    auto* heap = new std::vector<T>(std::move(v));
    nb::capsule owner(heap, [](void* p) noexcept { delete static_cast<std::vector<T>*>(p); });
    size_t shape[1] = {heap->size()};
    return nb::ndarray<nb::numpy, T>(heap->data(), 1, shape, owner).cast();
}

template <class T>
std::vector<T> numpy_to_vec(nb::handle part, const char* key) {
    auto a = nb::cast<nb::ndarray<const T, nb::ndim<1>, nb::c_contig, nb::device::cpu>>(part[key]);
    return std::vector<T>(a.data(), a.data() + a.shape(0));
}

/// One chain state as a dict (inspection and tests).
nb::dict chain_state_dict(const mlt::ChainState& c) {
    nb::dict d;
    d["chain_id"] = c.chain_id;
    nb::list u;
    for (const auto& v : c.u) {
        nb::list l;
        for (float x : v) l.append(x);
        u.append(l);
    }
    d["u"] = u;
    d["depth"] = c.depth;
    d["s"] = c.s;
    d["t"] = c.t;
    d["f_star"] = c.f_star;
    d["colour"] = nb::make_tuple(c.colour.x, c.colour.y, c.colour.z);
    return d;
}

nb::object to_numpy_2d(std::vector<float>&& v, int h, int w) {
    auto* heap = new std::vector<float>(std::move(v));
    nb::capsule owner(heap, [](void* p) noexcept { delete static_cast<std::vector<float>*>(p); });
    size_t shape[2] = {size_t(h), size_t(w)};
    return nb::ndarray<nb::numpy, float>(heap->data(), 2, shape, owner).cast();
}

nb::dict render_aovs_py(Scene& scene, const RenderSettings& settings, int samples) {
    AovResult res;
    {
        nb::gil_scoped_release release;
        res = render_aovs(scene, settings, samples);
    }
    nb::dict d;
    d["albedo"] = rgb_to_numpy(std::move(res.albedo), res.height, res.width);
    d["N"] = rgb_to_numpy(std::move(res.normal), res.height, res.width);
    d["Z"] = to_numpy_2d(std::move(res.depth), res.height, res.width);
    return d;
}

PyRenderResult render_py(Scene& scene, const RenderSettings& settings, nb::object progress, nb::object on_estimate) {
    ProgressCallback cb;
    EstimateCallback est;
    std::exception_ptr cb_error;
    if (!progress.is_none() && !PyCallable_Check(progress.ptr()))
        throw nb::type_error("render: progress must be a callable(done, total) or None");
    if (!on_estimate.is_none() && !PyCallable_Check(on_estimate.ptr()))
        throw nb::type_error("render: on_estimate must be a callable(work, seconds, relmse) or None");
    if (!progress.is_none() || !on_estimate.is_none()) {
        // an exception in either callback stops the frame after the current chunk
        cb = [&, has_progress = !progress.is_none()](uint64_t done, uint64_t total) -> bool {
            if (cb_error) return false;
            if (!has_progress) return true;
            nb::gil_scoped_acquire gil;
            try {
                nb::object r = progress(done, total);
                if (r.is_none()) return true;
                int truth = PyObject_IsTrue(r.ptr());
                if (truth < 0) throw nb::python_error();
                return truth != 0;
            } catch (...) {
                cb_error = std::current_exception();
                return false;
            }
        };
    }
    if (!on_estimate.is_none()) {
        est = [&](double work, double secs, double relmse, double) {
            if (cb_error) return;
            nb::gil_scoped_acquire gil;
            try {
                on_estimate(work, secs, relmse);
            } catch (...) {
                cb_error = std::current_exception();
            }
        };
    }
    RenderResult res;
    {
        nb::gil_scoped_release release;
        res = render(scene, settings, cb, est);
    }
    if (cb_error) std::rethrow_exception(cb_error);

    PyRenderResult out;
    out.image = rgb_to_numpy(std::move(res.image), res.height, res.width);
    out.variance = rgb_to_numpy(std::move(res.variance), res.height, res.width);
    out.robust = res.robust.empty() ? nb::none() : rgb_to_numpy(std::move(res.robust), res.height, res.width);
    out.direct = res.direct.empty() ? nb::none() : rgb_to_numpy(std::move(res.direct), res.height, res.width);
    if (res.bootstrap_f.empty()) {
        out.bootstrap_f = nb::none();
    } else {
        auto* heap = new std::vector<float>(std::move(res.bootstrap_f));
        nb::capsule owner(heap, [](void* p) noexcept { delete static_cast<std::vector<float>*>(p); });
        size_t shape[1] = {heap->size()};
        out.bootstrap_f = nb::ndarray<nb::numpy, float>(heap->data(), 1, shape, owner).cast();
    }
    out.cancelled = res.cancelled;
    if (res.group_images.empty()) {
        out.group_images = nb::none();
        out.group_weights = nb::none();
    } else {
        auto* heap = new std::vector<float>(std::move(res.group_images));
        nb::capsule owner(heap, [](void* p) noexcept { delete static_cast<std::vector<float>*>(p); });
        size_t shape[4] = {res.group_weights.size(), size_t(res.height), size_t(res.width), 3};
        out.group_images = nb::ndarray<nb::numpy, float>(heap->data(), 4, shape, owner).cast();
        nb::list w;
        for (double v : res.group_weights) w.append(v);
        out.group_weights = w;
    }
    out.mlt_states = std::move(res.mlt_states);
    out.mlt_start_states = std::move(res.mlt_start_states);
    out.mlt_part = nb::none();
    if (res.mlt_part) {
        MltPart& p = *res.mlt_part;
        nb::dict d;
        d["splat_lo"] = vec_to_numpy(std::move(p.splat_lo));
        d["splat_hi"] = vec_to_numpy(std::move(p.splat_hi));
        d["norm_counts"] = vec_to_numpy(std::move(p.norm_counts));
        d["norm_moments"] = vec_to_numpy(std::move(p.norm_moments));
        d["steps"] = p.steps;
        out.mlt_part = d;
    }
    const RenderStats& st = res.stats;
    nb::dict d;
    d["time_s"] = st.time_s;
    d["samples"] = st.samples;
    d["camera_rays"] = st.camera_rays;
    d["shadow_rays"] = st.shadow_rays;
    d["rays"] = st.rays;
    d["rays_per_s"] = st.rays_per_s;
    if (st.packets > 0) d["packet_queries"] = st.packets;
    if (st.lane_hits > 0) d["lane_hits"] = st.lane_hits;
    if (st.lens_lights > 0) d["lens_lights"] = st.lens_lights;
    if (st.caustic_casters > 0) d["caustic_casters"] = st.caustic_casters;
    if (st.mlt_expected_starts >= 0.0) {
        d["mlt_expected_starts"] = st.mlt_expected_starts;
        d["mlt_too_few_starts"] = st.mlt_too_few_starts;
    }
    if (st.emission_guiding > 0) d["emission_guiding"] = st.emission_guiding;
    if (st.caster_coverage >= 0) d["caster_coverage"] = st.caster_coverage;
    d["busy_s"] = st.busy_s;
    d["trace_s"] = st.trace_s;
    d["shade_s"] = st.shade_s;
    d["nan_samples"] = st.nan_samples;
    d["pixel_filter"] = st.pixel_filter;
    d["filter_radius"] = st.filter_radius;
    d["sampler"] = st.sampler;
    d["pixel_correlation"] = st.pixel_correlation;
    if (st.nan_samples > 0) {
        d["first_nan_pixel"] = nb::make_tuple(st.first_nan_x, st.first_nan_y);
        d["first_nan_sample"] = st.first_nan_sample;
    }
    d["threads"] = st.threads;
    d["integrator"] = st.integrator;
    d["spp"] = st.spp;
    d["seed"] = st.seed;
    d["cancelled"] = res.cancelled;
    d["stop_reason"] = res.stop_reason;
    if (std::isfinite(res.error_estimate)) {
        d["error_estimate"] = res.error_estimate;
        d["error_stderr"] = res.error_stderr;
    }
    if (!res.error_history.empty()) {
        nb::list h;
        for (const auto& r : res.error_history) h.append(nb::make_tuple(r[0], r[1], r[2], r[3]));
        d["error_history"] = h;
    }
    if (st.mlt.enabled) {
        const MltStats& m = st.mlt;
        d["b"] = m.b;
        d["b_stderr"] = m.b_stderr;
        d["b_bootstrap"] = m.b_bootstrap;
        d["b_bootstrap_stderr"] = m.b_bootstrap_stderr;
        d["bootstrap_samples"] = m.bootstrap_samples;
        d["bootstrap_nonzero"] = m.bootstrap_nonzero;
        d["bootstrap_probe"] = m.bootstrap_probe;
        d["bootstrap_probe_nonzero"] = m.bootstrap_probe_nonzero;
        d["chains"] = m.chains;
        d["mutations"] = m.mutations;
        d["mutations_per_pixel"] = m.mutations_per_pixel;
        d["large_step_probability"] = m.large_step_probability;
        d["sigma"] = m.sigma;
        nb::dict acc;
        acc["small_step"] = m.acceptance_small;
        acc["large_step"] = m.acceptance_large;
        d["acceptance"] = acc;
        nb::dict steps;
        steps["small_step"] = m.small_steps;
        steps["large_step"] = m.large_steps;
        d["steps"] = steps;
        d["max_rejection_streak"] = m.max_rejection_streak;
        d["long_streak_rejections"] = m.long_streak_rejections;
        if (st.integrator == "pssmlt") {
            d["path_sampler"] = m.path_sampler;
            d["imported_chains"] = m.imported_chains;
        }
        d["clamped_splats"] = m.clamped_splats;
        d["importance"] = m.importance;
        d["pilot_evaluations"] = m.pilot_evaluations;
        d["direct_evaluations"] = m.direct_evaluations;
        d["direct_alone"] = m.direct_alone;
        d["min_depth"] = m.min_depth;
        d["camera_technique"] = m.camera_technique;
        d["paths"] = m.paths;
        d["states_visited"] = m.states_visited;
        d["top_occupancy"] = m.top_occupancy;
        d["stuck_chains"] = m.stuck_chains;
        d["max_chain_share"] = m.max_chain_share;
        d["max_stay_share"] = m.max_stay_share;
        d["path_evaluations"] = m.path_evaluations;
        d["kernel_stats"] = nb::module_::import_("json").attr("loads")(m.kernel_stats_json);
        if (st.integrator == "cmlt") {
            d["path_sampler"] = m.path_sampler;
            d["imported_chains"] = m.imported_chains;
            d["tries"] = m.tries;
            d["inner_length"] = m.inner_length;
            d["inner"] = m.inner;
            d["packets"] = m.packets;
            d["packet_width"] = m.packet_width;
            d["packet_queries"] = m.packet_queries;
            d["packet_rays"] = m.packet_rays;
            d["packet_shadow_rays"] = m.packet_shadow_rays;
            d["packet_ray_share"] = st.rays > 0 ? double(m.packet_rays) / double(st.rays) : 0.0;
            d["bundle_rays"] = m.bundle_rays;
            d["bundle_busy_s"] = m.bundle_busy_s;
            d["bundle_trace_s"] = m.bundle_trace_s;
        }
    }
    out.stats = d;
    return out;
}


}  // namespace

void bind_render(nb::module_& m) {
    nb::class_<mlt::ChainStates>(
        m, "MltStates",
        "Final states of a pssmlt or cmlt render's chains (RenderResult.mlt_states), to start the "
        "next render's chains from (RenderSettings.mlt_initial_states). Opaque; "
        "to_bytes()/from_bytes() serialise it (integrators/mlt/chain_state.h).")
        .def("__len__", [](const mlt::ChainStates& s) { return s.chains.size(); })
        .def_prop_ro("path_sampler", [](const mlt::ChainStates& s) { return s.path_sampler; })
        .def("chain", [](const mlt::ChainStates& s, size_t i) {
                 if (i >= s.chains.size()) throw nb::index_error("MltStates.chain: index out of range");
                 return chain_state_dict(s.chains[i]);
             }, "i"_a,
             "Chain i's state: {'chain_id', 'u': [camera, light, connection] lists of primary "
             "samples (NaN = none), 'depth', 's', 't', 'f_star', 'colour'}")
        .def("to_bytes", [](const mlt::ChainStates& s) {
            const std::string b = s.to_bytes();
            return nb::bytes(b.data(), b.size());
        })
        .def_static("from_bytes", [](nb::bytes b) {
            try {
                return std::make_shared<mlt::ChainStates>(
                    mlt::ChainStates::from_bytes(std::string(b.c_str(), b.size())));
            } catch (const std::invalid_argument& e) {
                throw nb::value_error(e.what());
            }
        }, "data"_a);

    bind_settings(m);

    nb::class_<PyRenderResult>(m, "RenderResult")
        .def_ro("image", &PyRenderResult::image, "float32 (H, W, 3), row 0 at the top")
        .def_ro("variance", &PyRenderResult::variance,
                "float32 (H, W, 3), sample variance of each pixel's mean")
        .def_ro("robust", &PyRenderResult::robust,
                "float32 (H, W, 3), each pixel's mean without its largest and smallest pass or block (pssmlt/"
                "cmlt: the direct pass's; NaN where it has fewer than three), the relMSE estimate's "
                "denominator; None without one")
        .def_ro("direct", &PyRenderResult::direct,
                "pssmlt/cmlt with a direct pass: its float32 (H, W, 3) image, already part of "
                "`image`; None otherwise")
        .def_ro("bootstrap_f", &PyRenderResult::bootstrap_f,
                "pssmlt/cmlt: float32 (N,) f* of the bootstrap samples by index (the same "
                "points every frame with stored seeds); None otherwise")
        .def_ro("cancelled", &PyRenderResult::cancelled)
        .def_ro("group_images", &PyRenderResult::group_images,
                "pssmlt/cmlt with error_groups G >= 3: float32 (G, H, W, 3), the image of each "
                "chain group (chain c in group c mod G); None otherwise")
        .def_ro("group_weights", &PyRenderResult::group_weights,
                "the group images' weights (their chains' image normalisation counts); None "
                "without groups")
        .def_ro("stats", &PyRenderResult::stats)
        .def_ro("mlt_start_states", &PyRenderResult::mlt_start_states,
                "pssmlt/cmlt: MltStates every chain started the frame from; None otherwise")
        .def_ro("mlt_states", &PyRenderResult::mlt_states,
                "pssmlt/cmlt: MltStates, the final state of every chain; None otherwise")
        .def_ro("mlt_part", &PyRenderResult::mlt_part,
                "pssmlt/cmlt with settings.partial: the part's raw sums, a dict of numpy arrays "
                "(splat_lo uint64, splat_hi int64: the splat film's 128-bit words; norm_counts "
                "uint64, norm_moments float64: the bootstrap's and each chain's normalisation "
                "accumulator) and steps; None otherwise");

    m.def(
        "combine_mlt_parts",
        [](int width, int height, nb::list parts, nb::object direct) {
            std::vector<MltPart> owned(parts.size());
            std::vector<const MltPart*> ptrs;
            for (size_t i = 0; i < parts.size(); ++i) {
                nb::handle p = parts[i];
                owned[i].splat_lo = numpy_to_vec<uint64_t>(p, "splat_lo");
                owned[i].splat_hi = numpy_to_vec<int64_t>(p, "splat_hi");
                owned[i].norm_counts = numpy_to_vec<uint64_t>(p, "norm_counts");
                owned[i].norm_moments = numpy_to_vec<double>(p, "norm_moments");
                owned[i].steps = nb::cast<uint64_t>(p["steps"]);
                ptrs.push_back(&owned[i]);
            }
            std::vector<float> d;
            if (!direct.is_none()) {
                auto a = nb::cast<nb::ndarray<const float, nb::c_contig, nb::device::cpu>>(direct);
                d.assign(a.data(), a.data() + a.size());
            }
            RenderResult res;
            {
                nb::gil_scoped_release release;
                res = combine_mlt_parts(width, height, ptrs, d);
            }
            nb::dict st;
            st["b"] = res.stats.mlt.b;
            st["b_stderr"] = res.stats.mlt.b_stderr;
            st["mutations"] = res.stats.mlt.mutations;
            st["clamped_splats"] = res.stats.mlt.clamped_splats;
            return nb::make_tuple(rgb_to_numpy(std::move(res.image), height, width), st);
        },
        "width"_a, "height"_a, "parts"_a, "direct"_a.none(),
        "The image (float32 (H, W, 3)) of a pssmlt/cmlt frame rendered in parts "
        "(RenderResult.mlt_part of each, sorted by first chain, covering every chain once) "
        "and {b, b_stderr, mutations, clamped_splats}: the splat sums added exactly, b merged "
        "in chain order, `direct` (the direct pass's image assembled from the parts' rows, "
        "or None) added — bit for bit the single-process frame.");

    m.def("render", &render_py, "scene"_a, "settings"_a, "progress"_a = nb::none(), "on_estimate"_a = nb::none(),
          "Render one frame. progress(done, total) is called between chunks of samples per "
          "pixel on the calling thread; returning False cancels. With settings.target_error, "
          "on_estimate(work, seconds, relmse) is called with each estimate as it is made (work: "
          "passes for pt/bdpt, path evaluations per pixel for pssmlt/cmlt).");
    m.def(
        "mlt_resolve_paths",
        [](Scene& scene, const RenderSettings& settings) {
            if (scene.dirty()) scene.commit();
            return mlt::MltContext::resolve_paths(scene, settings).mlt_paths;
        },
        "scene"_a, "settings"_a,
        "settings.mlt_paths with 'auto' resolved for this scene ('caustics' where a material "
        "can be near-specular, else 'none'), as the pssmlt/cmlt frame resolves it.");
    m.def(
        "mlt_probe_starts",
        [](Scene& scene, const RenderSettings& settings) -> nb::object {
            settings.validate();
            if (scene.dirty()) scene.commit();
            if (!mlt::start_probe_applies(scene, settings)) return nb::none();
            mlt::StartProbe p;
            {
                nb::gil_scoped_release release;
                p = mlt::probe_starts(scene, settings);
            }
            nb::dict d;
            d["probe"] = p.probe;
            d["probe_nonzero"] = p.nonzero;
            d["bootstrap"] = p.bootstrap;
            d["expected_starts"] = p.expected;
            d["too_few"] = p.too_few;
            d["rays"] = p.counters.rays;
            return d;
        },
        "scene"_a, "settings"_a,
        "The start probe of settings.mlt_min_starts (mlt_frame.h, probe_starts) where it "
        "decides the frame (pssmlt/cmlt, mlt_paths auto resolving to caustics, auto bootstrap "
        "size, no given bootstrap or states), else None: a dict of the probe's samples and "
        "those with light, the bootstrap size, the expected starts and too_few (render the "
        "frame with mlt_paths none).");
    m.def(
        "render_pilot",
        [](Scene& scene, const RenderSettings& settings) {
            settings.validate();
            if (!scene.has_camera()) throw SceneError("pilot: the scene has no camera (call set_camera)");
            if (scene.dirty()) scene.commit();
            std::vector<float> img;
            {
                nb::gil_scoped_release release;
                PathCounters c;
                img = mlt::render_pilot(scene, settings, mlt::MltContext::pilot_spp(settings), c);
            }
            return rgb_to_numpy(std::move(img), settings.height, settings.width);
        },
        "scene"_a, "settings"_a,
        "The pilot image of the 'pixel' MLT importance (float32 (H, W, 3)): "
        "settings.pilot_spp (at most spp/8) path-traced samples per pixel in a stream of their own. "
        "Set it as settings.pilot to share one pilot between a render and its "
        "carry-over evaluations.");
    m.def(
        "importance_map",
        [](nb::ndarray<const float, nb::c_contig, nb::device::cpu> pilot) {
            if (pilot.ndim() != 3 || pilot.shape(2) != 3)
                throw std::invalid_argument("importance_map: expected a float32 (H, W, 3) pilot");
            const int h = int(pilot.shape(0)), w = int(pilot.shape(1));
            const std::vector<float> v(pilot.data(), pilot.data() + pilot.size());
            mlt::PixelImportance imp(v, w, h);
            std::vector<float> p = imp.importance();
            if (p.empty()) p.assign(size_t(w) * size_t(h), 1.f);
            return to_numpy_2d(std::move(p), h, w);
        },
        "pilot"_a,
        "P per pixel (float32 (H, W)) of the 'pixel' importance built from a pilot image: "
        "f* = luminance / P (all ones for a black pilot: the luminance target).");
    m.def("render_aovs", &render_aovs_py, "scene"_a, "settings"_a, "samples"_a = 4,
          "Integrator-independent AOV pass (first hits of `samples` jittered camera rays per "
          "pixel; uses settings.width/height/seed/threads). Returns {'albedo': (H, W, 3) mean "
          "diffuse colour (escape 0, analytic lights their radiance clamped to [0, 1]), 'N': "
          "(H, W, 3) world-space unit shading normal facing the camera (0 where nothing was "
          "hit), 'Z': (H, W) closest hit's distance along the camera axis (0 where nothing was "
          "hit)}, float32, row 0 at the top.");
}

}  // namespace cmlt::bindings
