#include "cameras/camera.h"

#include "sampling/warp.h"
#include "util/error.h"

#include <cmath>

namespace cmlt {

void CameraDesc::validate() const {
    auto pos = [](float v, const char* name) {
        if (!(v > 0.f) || !std::isfinite(v))
            CMLT_THROW(SceneError, "camera: " << name << " must be finite and > 0, got " << v);
    };
    auto fin = [](float v, const char* name) {
        if (!std::isfinite(v)) CMLT_THROW(SceneError, "camera: " << name << " must be finite, got " << v);
    };
    if (projection == Projection::perspective) pos(focal_length, "focal_length");
    pos(horizontal_aperture, "horizontal_aperture");
    pos(vertical_aperture, "vertical_aperture");
    fin(horizontal_aperture_offset, "horizontal_aperture_offset");
    fin(vertical_aperture_offset, "vertical_aperture_offset");
    if (!(near >= 0.f) || !std::isfinite(near))
        CMLT_THROW(SceneError, "camera: near must be finite and >= 0, got " << near);
    if (!(far > near))
        CMLT_THROW(SceneError, "camera: far (" << far << ") must be greater than near (" << near << ")");
    if (!(f_stop >= 0.f)) CMLT_THROW(SceneError, "camera: f_stop must be >= 0, got " << f_stop);
    if (!(focus_distance >= 0.f))
        CMLT_THROW(SceneError, "camera: focus_distance must be >= 0, got " << focus_distance);
    if (!std::isfinite(f_stop) || !std::isfinite(focus_distance))
        CMLT_THROW(SceneError, "camera: f_stop and focus_distance must be finite");
    pos(lens_unit, "lens_unit");
    Transform(transform, "camera");
}

Camera::Camera(const CameraDesc& desc, int width, int height)
    : m_desc(desc), m_xf(desc.transform, "camera"), m_width(width), m_height(height) {
    desc.validate();
    if (desc.projection == CameraDesc::Projection::perspective && desc.f_stop > 0.f &&
        desc.focus_distance > 0.f) {
        float r = desc.focal_length * desc.lens_unit / (2.f * desc.f_stop);
        m_lens_radius = (r > 0.f && std::isfinite(r)) ? r : 0.f;
    }
    m_pinhole.width = float(m_width);
    m_pinhole.height = float(m_height);
    m_pinhole.win_w = desc.horizontal_aperture;  // the window, in aperture units
    m_pinhole.win_h = desc.horizontal_aperture * float(height) / float(width);
    m_pinhole.offset_x = desc.horizontal_aperture_offset;
    m_pinhole.offset_y = desc.vertical_aperture_offset;
    m_pinhole.focal_length = desc.focal_length;
    m_pinhole.near = desc.near;
    m_pinhole.far = desc.far;
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) m_pinhole.m[a][b] = m_xf.m.m[a][b];
    m_pinhole.origin = m_xf.m.transform_point(Vec3(0.f));
}

Ray Camera::generate_ray(const Vec2& p_raster, const Vec2& u_lens) const {
    if (!has_lens()) return generate_ray(p_raster);
    Vec2 w = raster_to_window(p_raster);
    // Pinhole direction at depth 1, scaled to the plane of focus.
    Vec3 pf(w.x / m_desc.focal_length * m_desc.focus_distance,
            w.y / m_desc.focal_length * m_desc.focus_distance, -m_desc.focus_distance);
    Vec2 d = square_to_uniform_disk_concentric(u_lens);
    Vec3 pl(d.x * m_lens_radius, d.y * m_lens_radius, 0.f);
    Vec3 dc = normalize(pf - pl);
    // near / far are depths along -Z: t = depth / -dc.z.
    float inv = 1.f / -dc.z;
    Vec3 o = m_xf.m.transform_point(pl);
    Vec3 dw = normalize(m_xf.m.transform_vector(dc));
    return Ray(o, dw, m_desc.near * inv, m_desc.far * inv);
}

Vec2 Camera::raster_to_window(const Vec2& p) const {
    Vec2 w;
    raster_window(m_pinhole, p.x, p.y, &w.x, &w.y);
    return w;
}

Ray Camera::generate_ray(const Vec2& p_raster) const {
    if (m_desc.projection == CameraDesc::Projection::orthographic) {
        Vec2 w = raster_to_window(p_raster);
        Vec3 o = m_xf.m.transform_point(Vec3(0.1f * w.x, 0.1f * w.y, 0.f));
        Vec3 d = normalize(m_xf.m.transform_vector(Vec3(0.f, 0.f, -1.f)));
        return Ray(o, d, m_desc.near, m_desc.far);
    }
    Vec3 d;
    float tnear, tfar;
    pinhole_ray(m_pinhole, p_raster.x, p_raster.y, &d, &tnear, &tfar);
    return Ray(m_pinhole.origin, d, tnear, tfar);
}

bool Camera::pinhole_constants(PinholeConstants* c) const {
    if (m_desc.projection != CameraDesc::Projection::perspective || has_lens()) return false;
    *c = m_pinhole;
    return true;
}

Vec3 Camera::lens_point(const Vec2& u_lens) const {
    if (!has_lens()) return m_pinhole.origin;
    // As generate_ray: concentric disk of radius r in the camera's z = 0 plane.
    Vec2 d = square_to_uniform_disk_concentric(u_lens);
    return m_xf.m.transform_point(Vec3(d.x * m_lens_radius, d.y * m_lens_radius, 0.f));
}

bool Camera::lens_ray_to_raster(const Vec3& p_lens, const Vec3& d, Vec2* p_raster) const {
    if (!has_lens()) return world_to_raster(p_lens + d, p_raster);
    Vec3 pc = m_xf.inv.transform_point(p_lens);
    Vec3 dc = m_xf.inv.transform_vector(d);
    if (!(dc.z < 0.f)) return false;
    // Where the ray meets the plane of focus z = -focus; the pinhole ray through the
    // raster position sought passes through that point too (see generate_ray).
    float t = (m_desc.focus_distance + pc.z) / -dc.z;
    Vec3 pf = pc + dc * t;
    Vec2 w(m_desc.focal_length * pf.x / m_desc.focus_distance,
           m_desc.focal_length * pf.y / m_desc.focus_distance);
    *p_raster = window_to_raster(w);
    return std::isfinite(p_raster->x) && std::isfinite(p_raster->y);
}

Vec2 Camera::window_to_raster(const Vec2& w) const {
    return {((w.x - m_pinhole.offset_x) / m_pinhole.win_w + 0.5f) * m_pinhole.width,
            (0.5f - (w.y - m_pinhole.offset_y) / m_pinhole.win_h) * m_pinhole.height};
}

bool Camera::world_to_raster(const Vec3& p_world, Vec2* p_raster) const {
    Vec3 pc = m_xf.inv.transform_point(p_world);
    Vec2 w;
    if (m_desc.projection == CameraDesc::Projection::orthographic) {
        w = {pc.x * 10.f, pc.y * 10.f};
        if (!(pc.z < 0.f)) return false;
    } else {
        if (!(pc.z < 0.f)) return false;
        w = {m_desc.focal_length * pc.x / -pc.z, m_desc.focal_length * pc.y / -pc.z};
    }
    *p_raster = window_to_raster(w);
    return true;
}

}  // namespace cmlt
