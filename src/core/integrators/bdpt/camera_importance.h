#pragma once
/// \file Camera importance of a perspective camera, pinhole or thin lens, for BDPT's
/// camera connections (t = 1, light tracing) and its MIS densities.
///
/// pbrt-v4's PerspectiveCamera::We / PDF_We / SampleWi explain the same quantities. A
/// camera ray starts at a lens point (a Dirac position for the pinhole; uniform on the
/// lens disk, area density 1 / A_lens, for a thin lens) and takes the direction of a
/// uniform film position: per solid angle 1 / (A cos^3) whatever the lens point (A:
/// image-window area at distance 1; for a thin lens the window on the plane of focus,
/// seen from any lens point, subtends the same solid-angle density). The importance that
/// makes every camera ray's throughput 1 is We = 1 / (A cos^4) (pinhole, times the Dirac
/// of the position) or 1 / (A A_lens cos^4) (thin lens). Orthographic cameras have a
/// Dirac direction and cannot be connected to (no t = 1).
///
/// The camera is assumed rigid (no scale in its transform), as everywhere in cameras/.
#include "cameras/camera.h"
#include "math/vec.h"

namespace cmlt {

class CameraImportance {
public:
    /// The film window is the image grown by `margin` pixels on every side (the
    /// film positions a pixel filter reaches: PixelFilter::margin); light tracing
    /// reaches it and the importance is normalised over it.
    CameraImportance(const Camera& camera, int width, int height, float margin = 0.f);
    /// t = 1 is possible (perspective, with or without a lens).
    bool connectable() const { return m_perspective; }
    bool has_lens() const { return m_lens; }
    /// A point on the lens for u in [0,1)^2 (the camera position for a pinhole).
    Vec3 sample_lens(const Vec2& u) const { return m_camera.lens_point(u); }
    /// Area density of sample_lens's point: 1 / A_lens (1 for the pinhole's Dirac
    /// position, which cancels between strategies).
    float pdf_lens() const { return m_pdf_lens; }
    /// Solid-angle density of the camera generating direction w from lens point p_lens
    /// (0 outside the image).
    float pdf_dir(const Vec3& p_lens, const Vec3& w) const;
    /// Importance We of the ray leaving lens point p_lens along w (per unit lens area
    /// with a thin lens), and its raster position; 0 outside the image.
    float we(const Vec3& p_lens, const Vec3& w, Vec2* p_raster) const;
    /// Cosine of w with the viewing axis.
    float cos_axis(const Vec3& w) const { return dot(w, m_fwd); }
    const Camera& camera() const { return m_camera; }

private:
    /// Raster position of the ray (p_lens, w) if it is forward and inside the image.
    bool raster_of(const Vec3& p_lens, const Vec3& w, Vec2* p_raster) const;

    const Camera& m_camera;
    int m_width, m_height;
    float m_margin;
    Vec3 m_fwd;
    float m_area = 1.f;
    float m_pdf_lens = 1.f;
    bool m_perspective = true;
    bool m_lens = false;
};

}  // namespace cmlt
