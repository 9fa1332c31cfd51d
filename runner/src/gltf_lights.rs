//! glTF `KHR_lights_punctual`: lights without a surface, turned into what our renderer
//! has. A directional light is the scene's sun (a distant disk NEE samples by its cone);
//! point and spot lights become small emissive shapes that emit the same power, so every
//! integrator (NEE, MIS, RIS, ReSTIR) samples them like any other emitter.
//!
//! Units: glTF gives candela (point, spot) and lux (directional); divided by 683 lm/W they
//! are the radiometric W/sr and W/m² our radiances are in: Blender's exporter multiplies
//! its watts by 683 to write them, so a Blender scene comes back with its own light.
use glam::Vec3;
use kernels::types::{Material, Triangle};

/// Lumens per watt at 555 nm: glTF's photometric intensities over this are radiometric.
pub const LUMENS_PER_WATT: f32 = 683.0;

/// Radius of the sphere (or disc) standing in for a point (or spot) light, as a share of
/// the scene's bounding-box diagonal: small enough to look like a point from across the
/// scene (its light at a distance d differs from a point's by ~(r/d)²), large enough for
/// f32 positions.
pub const RADIUS_SHARE: f32 = 1e-3;

/// Subdivisions of a point light's icosphere (80 triangles).
const SPHERE_SUBDIVISIONS: u32 = 1;

/// Corners of a spot light's disc.
const DISC_CORNERS: usize = 16;

/// A directional light: the direction towards it and the irradiance it gives a surface
/// facing it (W/m² per channel).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneSun {
    pub direction: Vec3,
    pub irradiance: Vec3,
}

/// A point or spot light in world space: its position, its radiant intensity (W/sr per
/// channel; a spot's on its axis) and, for a spot, the direction it shines in.
#[derive(Clone, Copy, Debug)]
pub struct PointLight {
    pub position: Vec3,
    pub intensity: Vec3,
    pub spot: Option<Vec3>,
}

/// A light's colour × intensity over 683 lm/W, or why it cannot be used.
pub fn radiometric(colour: [f32; 3], intensity: f32) -> Result<Vec3, String> {
    let value = Vec3::from(colour).max(Vec3::ZERO) * (intensity / LUMENS_PER_WATT);
    if !value.is_finite() || intensity < 0.0 {
        return Err(format!(
            "intensity {intensity} × colour {colour:?} is not a finite, non-negative value"
        ));
    }
    Ok(value)
}

/// The emissive triangles and materials (appended after `first_material`) standing in for
/// `lights`, each of radius `radius`: a point light is an icosphere of uniform radiance
/// 4I / A (A its surface: a Lambertian emitter of area A and radiance L sends out πLA,
/// a point of intensity I 4πI); a spot light a one-sided disc facing along the spot with
/// radiance I / A, so its intensity on the axis is kept (off the axis it falls off as the
/// cosine, not at the cone's angles).
pub fn emitters(
    lights: &[PointLight],
    radius: f32,
    first_material: u32,
) -> Result<(Vec<Triangle>, Vec<Material>), String> {
    let mut triangles = Vec::new();
    let mut materials = Vec::new();
    for light in lights {
        let material = first_material + materials.len() as u32;
        let shape: Vec<Triangle> = match light.spot {
            None => {
                crate::generate::icosphere(light.position, radius, SPHERE_SUBDIVISIONS, material)
            }
            Some(axis) => disc(light.position, axis, radius, material),
        };
        let area: f32 = shape.iter().map(|t| 0.5 * t.cross().length()).sum();
        let radiance = match light.spot {
            None => 4.0 * light.intensity / area,
            Some(_) => light.intensity / area,
        };
        if !(radiance.is_finite() && radiance.max_element() <= crate::scene::MAX_RADIANCE) {
            return Err(format!(
                "a light of intensity {} W/sr needs radiance {radiance} on its {radius:e}-wide \
                 stand-in, beyond {:e}",
                light.intensity,
                crate::scene::MAX_RADIANCE
            ));
        }
        materials.push(Material::new(Vec3::ZERO, radiance));
        triangles.extend(shape);
    }
    Ok((triangles, materials))
}

/// A flat disc of `DISC_CORNERS` corners around `centre`, emitting side towards `axis`.
fn disc(centre: Vec3, axis: Vec3, radius: f32, material: u32) -> Vec<Triangle> {
    let axis = axis.normalize();
    let (t, b) = axis.any_orthonormal_pair();
    // t × b = axis: corners counter-clockwise seen from the front.
    let (t, b) = if t.cross(b).dot(axis) > 0.0 {
        (t, b)
    } else {
        (b, t)
    };
    let corner = |i: usize| {
        let phi = std::f32::consts::TAU * i as f32 / DISC_CORNERS as f32;
        centre + radius * (phi.cos() * t + phi.sin() * b)
    };
    (0..DISC_CORNERS)
        .map(|i| Triangle::new(centre, corner(i), corner(i + 1), material))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point light's sphere sends out the point's power 4πI: its radiance times π times
    /// its area.
    #[test]
    fn a_point_lights_sphere_emits_its_power() {
        let intensity = Vec3::new(2.0, 3.0, 5.0);
        let light = PointLight {
            position: Vec3::new(1.0, 2.0, 3.0),
            intensity,
            spot: None,
        };
        let (triangles, materials) = emitters(&[light], 0.01, 7).unwrap();
        assert!(triangles.iter().all(|t| t.material == 7));
        let area: f32 = triangles.iter().map(|t| 0.5 * t.cross().length()).sum();
        let power = Vec3::from(materials[0].emission) * std::f32::consts::PI * area;
        let expected = 4.0 * std::f32::consts::PI * intensity;
        assert!((power - expected).abs().max_element() < 1e-4 * expected.max_element());
    }

    /// A spot's disc faces along the spot, and its intensity on the axis (radiance × area)
    /// is the spot's.
    #[test]
    fn a_spot_lights_disc_faces_along_the_spot() {
        let axis = Vec3::new(0.0, -1.0, 1.0).normalize();
        let light = PointLight {
            position: Vec3::ZERO,
            intensity: Vec3::splat(10.0),
            spot: Some(axis),
        };
        let (triangles, materials) = emitters(&[light], 0.5, 0).unwrap();
        let area: f32 = triangles.iter().map(|t| 0.5 * t.cross().length()).sum();
        for t in &triangles {
            assert!((t.cross().normalize() - axis).length() < 1e-5);
        }
        let on_axis = Vec3::from(materials[0].emission) * area;
        assert!((on_axis - Vec3::splat(10.0)).abs().max_element() < 1e-4);
    }

    #[test]
    fn photometric_intensities_become_radiometric() {
        let v = radiometric([1.0, 0.5, 0.0], 683.0).unwrap();
        assert_eq!(v, Vec3::new(1.0, 0.5, 0.0));
        assert!(radiometric([1.0; 3], f32::INFINITY).is_err());
        assert!(radiometric([1.0; 3], -1.0).is_err());
    }
}
