// Camera importance for BDPT's camera connections; see camera_importance.h.
#include "integrators/bdpt/camera_importance.h"

#include "math/safe_math.h"

#include <cmath>

namespace cmlt {

CameraImportance::CameraImportance(const Camera& camera, int width, int height, float margin)
    : m_camera(camera), m_width(width), m_height(height), m_margin(margin) {
    const CameraDesc& d = camera.desc();
    m_perspective = d.projection == CameraDesc::Projection::perspective;
    m_lens = m_perspective && camera.has_lens();
    m_fwd = normalize(d.transform.transform_vector(Vec3(0.f, 0.f, -1.f)));
    // Image window at distance 1 (see cameras/camera.h for the framing).
    float fl = d.focal_length;
    float ww = d.horizontal_aperture / fl;
    float wh = d.horizontal_aperture * float(height) / float(width) / fl;
    m_area = ww * wh;
    if (margin != 0.f)  // the window grown by the margin
        m_area *= float((double(width) + 2.0 * margin) * (double(height) + 2.0 * margin) /
                        (double(width) * double(height)));
    if (m_lens) {
        const float r = camera.lens_radius();
        m_pdf_lens = 1.f / (k_pi * r * r);
    }
}

bool CameraImportance::raster_of(const Vec3& p_lens, const Vec3& w, Vec2* p_raster) const {
    if (!(dot(w, m_fwd) > 0.f)) return false;
    if (!m_camera.lens_ray_to_raster(p_lens, w, p_raster)) return false;
    return p_raster->x >= -m_margin && p_raster->x < float(m_width) + m_margin && p_raster->y >= -m_margin &&
           p_raster->y < float(m_height) + m_margin;
}

float CameraImportance::pdf_dir(const Vec3& p_lens, const Vec3& w) const {
    if (!m_perspective) return 1.f;  // Dirac direction: cancels in every weight (no t = 1)
    Vec2 pr;
    if (!raster_of(p_lens, w, &pr)) return 0.f;
    float c = dot(w, m_fwd);
    return 1.f / (m_area * c * c * c);
}

float CameraImportance::we(const Vec3& p_lens, const Vec3& w, Vec2* p_raster) const {
    if (!m_perspective) return 0.f;
    if (!raster_of(p_lens, w, p_raster)) return 0.f;
    float c = dot(w, m_fwd);
    float c2 = c * c;
    // Per unit lens area with a lens (times the lens density 1 / A_lens); the pinhole's
    // Dirac position has pdf_lens() = 1.
    return m_pdf_lens / (m_area * c2 * c2);
}

}  // namespace cmlt
