//! Pinhole camera rays. Pixel (0, 0) is the top-left; image x goes right and image y down.
use crate::glam::Vec3;
use crate::intersect::Ray;
use crate::math::vec3;
use crate::rng::Rng;
use crate::types::Camera;

/// Ray through the point (x + jx, y + jy) of the image, jx, jy in [0, 1) (box filter).
pub fn primary_ray(cam: &Camera, width: u32, height: u32, x: f32, y: f32) -> Ray {
    let ndc_x = 2.0 * x / width as f32 - 1.0;
    let ndc_y = 1.0 - 2.0 * y / height as f32;
    let dir = vec3(cam.forward) + vec3(cam.right) * ndc_x + vec3(cam.up) * ndc_y;
    Ray::new(vec3(cam.eye), dir.normalize())
}

/// The ray through a uniformly jittered point of pixel (x, y) (box filter); draws two
/// numbers from `rng`.
pub fn jittered_ray(cam: &Camera, width: u32, height: u32, x: u32, y: u32, rng: &mut Rng) -> Ray {
    let jx = rng.next_f32();
    let jy = rng.next_f32();
    primary_ray(cam, width, height, x as f32 + jx, y as f32 + jy)
}

/// The angle a pixel spans (at the image's centre): how fast the cone of directions
/// through one pixel widens with distance (`bvh::surface_hit`'s `cone_width`).
pub fn pixel_spread(cam: &Camera, height: u32) -> f32 {
    2.0 * vec3(cam.up).length() / height.max(1) as f32
}

/// Build the camera from a look-at description; `fov_y_degrees` is the vertical field of
/// view. The world is right-handed: right = forward × up.
pub fn look_at(eye: Vec3, target: Vec3, up: Vec3, fov_y_degrees: f32, aspect: f32) -> Camera {
    let forward = (target - eye).normalize();
    let right = forward.cross(up).normalize();
    let true_up = right.cross(forward);
    let half_h = crate::math::tan(0.5 * fov_y_degrees.to_radians());
    let half_w = half_h * aspect;
    Camera {
        eye: eye.to_array(),
        _pad0: 0.0,
        forward: forward.to_array(),
        _pad1: 0.0,
        right: (right * half_w).to_array(),
        _pad2: 0.0,
        up: (true_up * half_h).to_array(),
        _pad3: 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_corners_and_handedness() {
        let cam = look_at(Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0), Vec3::Y, 90.0, 2.0);
        let c = primary_ray(&cam, 200, 100, 100.0, 50.0);
        assert!((c.dir - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-6);
        // Top-left corner: left (-x, right-handed looking down -z) and up (+y).
        let tl = primary_ray(&cam, 200, 100, 0.0, 0.0);
        let expect = Vec3::new(-2.0, 1.0, -1.0).normalize();
        assert!((tl.dir - expect).length() < 1e-6, "{:?}", tl.dir);
    }
}
