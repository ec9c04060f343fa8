#include "integrators/path/path_tracer.h"

#include "integrators/path/path_tracer_impl.h"

namespace cmlt {

template Spectrum PathTracer::li<PixelSampler>(const Ray&, PixelSampler&, PathCounters&,
                                              const SceneHit*) const;

}  // namespace cmlt
