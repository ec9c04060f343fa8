#pragma once
/// \file Material table rows (rendering-space linear RGB).
///
/// Today a material is Lambertian reflection plus (two-sided) emission. The
/// UsdPreviewSurface issue adds lobes here and in materials/bsdf.h.
#include "math/vec.h"

namespace cmlt {

struct Material {
    Spectrum diffuse{0.18f, 0.18f, 0.18f};
    Spectrum emission{0.f, 0.f, 0.f};
    bool is_emissive() const { return max_component(emission) > 0.f; }
};

}  // namespace cmlt
