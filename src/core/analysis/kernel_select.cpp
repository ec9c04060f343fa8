#include "analysis/kernel_select.h"

namespace cmlt {

bool exact_lambertian(const Material& m) {
    if (!m.preview) return false;
    // inputs of the lobes the diffuse-only kernel drops must be constants
    if (m.tex_specular >= 0 || m.pv_specular >= 0 || m.tex_metallic >= 0 || m.pv_metallic >= 0 ||
        m.tex_clearcoat >= 0 || m.pv_clearcoat >= 0 || m.tex_opacity >= 0 || m.pv_opacity >= 0)
        return false;
    if (!(m.clearcoat <= 0.f)) return false;  // NaN clamps to the default 0 too, but say no
    // opaque: opacity 1, or a cut-out threshold the constant opacity passes
    const bool opaque = m.opacity_threshold > 0.f ? !(m.opacity < m.opacity_threshold)
                                                  : m.opacity >= 1.f;
    if (!opaque) return false;
    // F0 = 0 (preview_surface.cpp note 1): no specular lobe, Lambert colour = diffuseColor
    if (m.use_specular_workflow) return m.specular.x == 0.f && m.specular.y == 0.f &&
                                        m.specular.z == 0.f;
    return m.metallic == 0.f && m.ior == 1.f;
}

}  // namespace cmlt
