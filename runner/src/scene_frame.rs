//! The coordinates the kernels see: a file's, moved to the origin and scaled up by a power
//! of two where the file's would cost precision.
//!
//! Rays leave a surface from a point offset off it (`kernels::bvh::offset_ray_origin`,
//! Wächter & Binder): by 256 ulps of the point's coordinates, and by 1/65536 near the
//! origin, where ulps vanish. Both assume a scene of about unit size around the origin. A
//! scene a few millimetres across in metres (a screw) gets offsets that are a good share
//! of its details, and a small scene far from the origin (a building in a city's
//! coordinates) gets ulps as coarse as its details: contact shadows and AO go, light leaks
//! in. Rocks-2k scaled by 1e-5 rendered with 47% of its AO pixels and 29% of its MIS pixels
//! different from the unscaled scene, and by 1e-7 its MIS image was black. So the loader
//! moves such scenes: to the origin along the axes where the scene is far from it, and up
//! by a power of two where it is small. Both are exact where they apply (a difference of
//! two floats within a factor of two of each other, Sterbenz; a power of two), so vertices
//! shared by triangles stay shared and watertightness is kept. Everything else that the
//! user gives in the file's units (`--eye`, `--target`, the file's camera, `--ao-distance`)
//! goes through the same frame. An OBJ file's positions are read in f64 and moved before
//! they are rounded to f32 (`scene::centre_obj_vertices`): georeferenced exports (UTM
//! coordinates in the millions of metres) keep their centimetres.
use glam::{DVec3, Vec3};

/// A scene whose bounding-box diagonal is below this is scaled up to it (by the smallest
/// power of two that gets there): the offset near the origin, 1/65536, is then at most
/// 1.5e-5 of the scene.
const MIN_EXTENT: f32 = 1.0;
/// A scene is moved to the origin along each axis where its centre is further from it than
/// this many times its diagonal: its offsets (256 ulps) would otherwise be above ~2e-4 of
/// it.
const FAR_FROM_ORIGIN: f32 = 8.0;

/// File coordinates to the kernels': p ↦ (p − centre) · scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneFrame {
    /// In f64: a file read in f64 may have been moved before its rounding to f32.
    pub centre: DVec3,
    /// A power of two, at least 1.
    pub scale: f32,
}

impl Default for SceneFrame {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl SceneFrame {
    /// The file's own coordinates.
    pub const IDENTITY: Self = Self {
        centre: DVec3::ZERO,
        scale: 1.0,
    };

    /// The frame for a scene with these corners (non-finite ones are skipped: such
    /// triangles are dropped later).
    pub fn fitting(corners: impl Iterator<Item = Vec3>) -> Self {
        let (lo, hi) = crate::scene::bounds_of(corners.filter(|p| p.is_finite()));
        let extent = (hi - lo).length();
        if !(extent > 0.0 && extent.is_finite()) {
            return Self::IDENTITY;
        }
        let centre = far_centre(lo.as_dvec3(), hi.as_dvec3());
        let mut scale = 1.0f32;
        while extent * scale < MIN_EXTENT {
            scale *= 2.0;
        }
        Self { centre, scale }
    }

    pub fn is_identity(&self) -> bool {
        *self == Self::IDENTITY
    }

    /// A position in the file's coordinates, in the kernels'.
    pub fn point(&self, p: Vec3) -> Vec3 {
        self.position(p.as_dvec3())
    }

    /// A position in the file's coordinates read in f64 (a camera's), in the kernels'.
    pub fn position(&self, p: DVec3) -> Vec3 {
        ((p - self.centre) * self.scale as f64).as_vec3()
    }

    /// A length in the file's units, in the kernels'.
    pub fn length(&self, d: f32) -> f32 {
        d * self.scale
    }
}

/// The centre to move a box of points (lo, hi) to: its middle along each axis where that is
/// more than `FAR_FROM_ORIGIN` diagonals from the origin, 0 along the others; 0 for an
/// empty or unbounded box.
pub fn far_centre(lo: DVec3, hi: DVec3) -> DVec3 {
    let extent = (hi - lo).length();
    if !(extent > 0.0 && extent.is_finite()) {
        return DVec3::ZERO;
    }
    // lo + half the span, not (lo + hi) / 2, which can overflow.
    let middle = lo + 0.5 * (hi - lo);
    let far = |m: f64| {
        if m.abs() > FAR_FROM_ORIGIN as f64 * extent {
            m
        } else {
            0.0
        }
    };
    DVec3::new(far(middle.x), far(middle.y), far(middle.z))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scenes_of_usual_size_near_the_origin_keep_their_coordinates() {
        let corners = [Vec3::new(-10.0, 0.0, -10.0), Vec3::new(10.0, 5.0, 40.0)];
        assert!(SceneFrame::fitting(corners.into_iter()).is_identity());
    }

    #[test]
    fn small_scenes_are_scaled_up_by_a_power_of_two() {
        let corners = [Vec3::ZERO, Vec3::new(3e-6, 1e-6, 0.0)];
        let f = SceneFrame::fitting(corners.into_iter());
        assert_eq!(f.centre, DVec3::ZERO);
        assert_eq!(f.scale.log2().fract(), 0.0, "{}", f.scale);
        let extent = corners[1].length() * f.scale;
        assert!((MIN_EXTENT..2.0 * MIN_EXTENT).contains(&extent), "{extent}");
        // Exact: a corner scaled back is the corner.
        assert_eq!(f.point(corners[1]) / f.scale, corners[1]);
    }

    #[test]
    fn far_scenes_move_to_the_origin_exactly_along_their_far_axes() {
        let corners = [Vec3::new(5000.0, -2.0, 0.0), Vec3::new(5010.25, 3.0, 7.0)];
        let f = SceneFrame::fitting(corners.into_iter());
        assert_eq!(f.scale, 1.0);
        assert_eq!(f.centre, DVec3::new(5005.125, 0.0, 0.0));
        for p in corners {
            // Sterbenz: the difference is exact, so adding the centre back restores p.
            assert_eq!(f.point(p) + f.centre.as_vec3(), p);
        }
    }

    #[test]
    fn points_without_extent_keep_the_identity() {
        assert!(SceneFrame::fitting([Vec3::ONE; 3].into_iter()).is_identity());
        assert!(SceneFrame::fitting(core::iter::empty()).is_identity());
        let nan = [Vec3::NAN, Vec3::ZERO, Vec3::X];
        assert!(SceneFrame::fitting(nan.into_iter()).is_identity());
    }
}
