#pragma once
/// \file UsdGeom.Camera as a pinhole (or orthographic) camera.
///
/// The camera looks down local -Z with +Y up. The image-plane window, in aperture units
/// at distance `focal_length`, is fitted like usdrecord's default framing: the horizontal
/// aperture spans the image width, and the vertical extent follows the render
/// resolution's aspect (vertical_aperture is stored, not used for framing):
///   x in hoff + [-1/2, 1/2] * ha,   y in voff + [-1/2, 1/2] * ha * height / width.
/// Raster coordinates: (0, 0) is the top-left corner of the image, x right, y down;
/// pixel (i, j) covers [i, i+1) x [j, j+1).
///
/// Orthographic: the window is the same in *tenths of world units* (USD's aperture
/// unit), at the camera plane; rays are parallel to -Z.
///
/// near/far clip the ray by depth along -Z (for a transform without scale).
/// Depth of field (thin lens): only for a perspective camera with f_stop > 0 and
/// focus_distance > 0 (otherwise a pinhole, bit-identical to the camera without the
/// feature). The lens is a disk in the camera's z = 0 plane of radius
///   r = focal_length * lens_unit / (2 f_stop)   (metres; lens_unit = metres per lens unit)
/// and the plane of focus is z = -focus_distance (metres, camera space). A ray through
/// raster p and lens sample u starts at the concentric-disk point r d(u) and passes
/// through the point of the plane of focus that the pinhole ray through p reaches, so
/// every ray of a pixel converges there, and a point at depth z spreads over a circle
/// of confusion of diameter 2 r |z - focus| / z on the plane of focus (in the image:
/// times focal / focus). The lens sample comes from its own dimension
/// (k_lens_dimension, sampling/rng_domains.h) of the sample's camera-path stream, drawn
/// only with a lens; the shutter time of a motion-blurred sample likewise
/// (k_shutter_time_dimension).
#include "math/mat4.h"
#include "math/ray.h"

#include <cmath>
#include <cstdint>

namespace cmlt {

struct CameraDesc {
    enum class Projection { perspective, orthographic };
    Mat4 transform;  ///< camera -> world
    float focal_length = 50.f;
    float horizontal_aperture = 20.955f;
    float vertical_aperture = 15.2908f;
    float horizontal_aperture_offset = 0.f;
    float vertical_aperture_offset = 0.f;
    float near = 0.01f;
    float far = 1e6f;
    float f_stop = 0.f;
    float focus_distance = 0.f;
    float lens_unit = 0.001f;  ///< metres per focal-length unit (mm: 0.001), thin lens only
    Projection projection = Projection::perspective;

    /// Throws SceneError naming the bad field.
    void validate() const;
};

/// What a perspective pinhole camera's rays are made of (Camera::pinhole_constants), for
/// the camera rays computed in lanes (integrators/path/diffuse_lanes.h, camera_directions).
struct PinholeConstants {
    float width = 0.f, height = 0.f;  ///< the raster size, as floats
    float win_w = 0.f, win_h = 0.f, offset_x = 0.f, offset_y = 0.f, focal_length = 1.f;
    float near = 0.f, far = 0.f;
    double m[3][3] = {};  ///< camera -> world, the linear part
    Vec3 origin;
};

#if defined(__GNUC__)
#define CMLT_CAMERA_INLINE inline __attribute__((always_inline))
#else
#define CMLT_CAMERA_INLINE inline
#endif

/// The image-plane window position (aperture units) of raster position (fx, fy): every
/// camera's (Camera::raster_to_window), and the start of pinhole_ray.
CMLT_CAMERA_INLINE void raster_window(const PinholeConstants& c, float fx, float fy, float* wx, float* wy) {
    *wx = c.offset_x + (fx / c.width - 0.5f) * c.win_w;
    *wy = c.offset_y + (0.5f - fy / c.height) * c.win_h;
}

/// The pinhole ray of raster position (fx, fy): its direction (unit length; 0 if it has
/// none) and its interval (the near and far depths along -Z as distances along the
/// ray). Camera::generate_ray's perspective rays and pt's camera lanes
/// (camera_directions) are both this function, so they agree bit for bit; always inlined,
/// so that the lanes' loop vectorises.
CMLT_CAMERA_INLINE void pinhole_ray(const PinholeConstants& c, float fx, float fy, Vec3* d, float* tnear,
                                    float* tfar) {
    // the window position (aperture units), the direction at depth 1 and its length, the
    // camera's linear part in doubles, the normalisation (Vec3::operator/ multiplies by
    // the reciprocal)
    float wx, wy;
    raster_window(c, fx, fy, &wx, &wy);
    const float cx = wx / c.focal_length, cy = wy / c.focal_length, cz = -1.f;
    const float len = std::sqrt(cx * cx + cy * cy + cz * cz);
    const double x = cx, y = cy, z = cz;
    const float vx = float(c.m[0][0] * x + c.m[0][1] * y + c.m[0][2] * z);
    const float vy = float(c.m[1][0] * x + c.m[1][1] * y + c.m[1][2] * z);
    const float vz = float(c.m[2][0] * x + c.m[2][1] * y + c.m[2][2] * z);
    const float l = std::sqrt(vx * vx + vy * vy + vz * vz);
    const float r = 1.f / l;
    const bool ok = l > 0.f;
    d->x = ok ? vx * r : 0.f;
    d->y = ok ? vy * r : 0.f;
    d->z = ok ? vz * r : 0.f;
    *tnear = c.near * len;
    *tfar = c.far * len;
}

class Camera {
public:
    Camera(const CameraDesc& desc, int width, int height);

    /// Primary ray through raster position `p_raster`; direction is unit length.
    Ray generate_ray(const Vec2& p_raster) const;
    /// Primary ray through `p_raster` and lens position `u_lens` in [0,1)^2 (thin lens);
    /// the pinhole ray when the camera has no lens.
    Ray generate_ray(const Vec2& p_raster, const Vec2& u_lens) const;
    /// A perspective camera without a lens: its constants (generate_ray(p_raster) is then
    /// camera_directions' lane for every p_raster, the same floats).
    bool pinhole_constants(PinholeConstants* c) const;
    /// Thin lens in use (perspective, f_stop > 0, focus_distance > 0).
    bool has_lens() const { return m_lens_radius > 0.f; }
    /// Lens radius in metres (0 for a pinhole).
    float lens_radius() const { return m_lens_radius; }
    /// Project a world point to raster coordinates; false if behind the camera.
    bool world_to_raster(const Vec3& p_world, Vec2* p_raster) const;
    /// World position of lens sample `u_lens` in [0,1)^2: the origin of
    /// generate_ray(p, u_lens) for every p (thin lens; the camera position otherwise).
    Vec3 lens_point(const Vec2& u_lens) const;
    /// Raster position of the camera ray leaving the lens at world point `p_lens` in
    /// direction `d` (world, toward the scene): the film position whose rays pass through
    /// the point where this ray meets the plane of focus (thin lens), or the projection
    /// of p_lens + d (pinhole, p_lens the camera position). Inverse of generate_ray in
    /// the sense generate_ray(p, u) passes through (lens_point(u), p). False if the ray
    /// does not go forward. Perspective cameras only.
    bool lens_ray_to_raster(const Vec3& p_lens, const Vec3& d, Vec2* p_raster) const;

    const CameraDesc& desc() const { return m_desc; }
    Vec3 position() const { return m_pinhole.origin; }

private:
    /// Image-plane window position (aperture units) of a raster position.
    Vec2 raster_to_window(const Vec2& p) const;
    /// Raster position of an image-plane window position (aperture units).
    Vec2 window_to_raster(const Vec2& w) const;

    CameraDesc m_desc;
    Transform m_xf;
    /// generate_ray(p_raster)'s constants for a perspective camera (pinhole_ray); for
    /// every camera, its raster and window (raster_window) and its position, the origin
    /// m_xf.m.transform_point(0), computed once
    PinholeConstants m_pinhole;
    int m_width, m_height;
    float m_lens_radius = 0.f;
};

}  // namespace cmlt
