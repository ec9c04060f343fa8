#pragma once
#include "math/vec.h"

namespace cmlt {

/// A sampled direction. For a Dirac lobe (`is_delta`), `f` and `pdf` carry the same
/// delta factor, so `f * |cos| / pdf` is the usual weight and pdf is set to 1.
struct BsdfSample {
    Vec3 wi;
    Spectrum f{0.f};
    float pdf = 0.f;
    bool is_delta = false;
    bool valid() const { return pdf > 0.f; }
};

}  // namespace cmlt
