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
/// f_stop / focus_distance are kept for the thin-lens issue; today it is a pinhole.
#include "math/mat4.h"
#include "math/ray.h"

#include <cstdint>

namespace cmlt {

/// Motion blur: the shutter time of a camera sample (Ray::time, in [0, 1) over
/// [shutter open, shutter close]) is drawn from its own dimension of the sample's
/// camera-path random stream, far above any dimension a path uses. Only when the scene
/// has motion-blurred geometry (Scene::motion_blur()) is it drawn; otherwise rays keep
/// time 0 and every other random number of the sample is the same either way, so a
/// scene that does not move renders bit-identically with or without the feature.
constexpr uint32_t k_shutter_time_dimension = 0xFFFFFF00u;

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
    Projection projection = Projection::perspective;

    /// Throws SceneError naming the bad field.
    void validate() const;
};

class Camera {
public:
    Camera(const CameraDesc& desc, int width, int height);

    /// Primary ray through raster position `p_raster`; direction is unit length.
    Ray generate_ray(const Vec2& p_raster) const;
    /// Project a world point to raster coordinates; false if behind the camera.
    bool world_to_raster(const Vec3& p_world, Vec2* p_raster) const;

    const CameraDesc& desc() const { return m_desc; }
    Vec3 position() const { return m_xf.m.transform_point(Vec3(0.f)); }

private:
    /// Image-plane window position (aperture units) of a raster position.
    Vec2 raster_to_window(const Vec2& p) const;

    CameraDesc m_desc;
    Transform m_xf;
    int m_width, m_height;
    float m_win_w, m_win_h;  ///< window size in aperture units
};

}  // namespace cmlt
