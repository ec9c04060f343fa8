#pragma once
/// \file The random sources the path-sampling routines read, Tungsten's
/// PathSampleGenerator idea: a tracer never knows whether its numbers are independent
/// (a pixel sample) or a Markov chain's primary samples (Metropolis), so one routine
/// serves every integrator.
///
/// PathSampler (static: the routines are templates; PathTracer::li, PssmltTracer):
///   void set_dimension(uint32_t d);  // jump to dimension d (each bounce owns a range)
///   float get1d();                   // the next dimension's value in [0, 1)
///   Vec2 get2d();                    // the next dimension's two values in [0, 1)
/// StreamSampler, a PathSampler with three independent streams (camera, light,
/// connection; pbrt-v4's MLTSampler), so a camera subpath that reads more or fewer
/// numbers never shifts the light subpath's:
///   void start_stream(uint32_t stream);  // continue with that stream, from dimension 0
/// Implementations: PixelSampler (sampling/rng.h), mlt::MltSampler
/// (integrators/mlt/mlt_sampler.h), coherent::PointSampler (integrators/cmlt/cmlt_state.h).
///
/// BdptSampler (dynamic): the streams as BDPT's subpath and connection code reads them,
/// a virtual interface so that code is compiled once (bdpt/*.cpp) for every source —
/// PixelStreamSampler (bdpt/path_sampler.h) and BdptStreamAdapter over any StreamSampler
/// (integrators/mlt/pssmlt_tracer.h). The call per number is the price of that; a
/// profile has not asked to template the BDPT translation units instead.
#include "math/vec.h"

#include <cstdint>
#include <type_traits>
#include <utility>

namespace cmlt {

/// Does S have the PathSampler interface (see the file comment)?
template <class S, class = void>
struct is_path_sampler : std::false_type {};
template <class S>
struct is_path_sampler<S, std::void_t<decltype(std::declval<S&>().set_dimension(uint32_t(0))),
                                      decltype(float(std::declval<S&>().get1d())),
                                      decltype(Vec2(std::declval<S&>().get2d()))>> : std::true_type {};
template <class S>
inline constexpr bool is_path_sampler_v = is_path_sampler<S>::value;

/// Does S have the StreamSampler interface (a PathSampler with start_stream)?
template <class S, class = void>
struct is_stream_sampler : std::false_type {};
template <class S>
struct is_stream_sampler<S, std::void_t<decltype(std::declval<S&>().start_stream(uint32_t(0)))>>
    : std::bool_constant<is_path_sampler_v<S>> {};
template <class S>
inline constexpr bool is_stream_sampler_v = is_stream_sampler<S>::value;

/// The random source of BDPT: three independent streams (camera subpath, light subpath,
/// connections).
class BdptSampler {
public:
    enum Stream : int { k_camera = 0, k_light = 1, k_connection = 2 };
    virtual ~BdptSampler() = default;
    /// Continue with stream `index` (0 camera, 1 light, 2 connection), from its start
    /// the first time it is used in this sample.
    virtual void start_stream(int index) = 0;
    virtual float next1d() = 0;
    virtual Vec2 next2d() = 0;
};

}  // namespace cmlt
