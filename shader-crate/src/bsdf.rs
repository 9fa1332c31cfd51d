//! The BSDF family: Lambertian diffuse, GGX microfacet conductor (a mirror when smooth),
//! GGX dielectric (glass, water; smooth or rough) and a diffuse base under a dielectric
//! coat (plastic, varnish). Every lobe is a pure function of local directions in the
//! shading frame (z = shading normal, turned to the side `wo` is on), with
//! - `eval(wo, wi)`: f(wo, wi) · |cos θi| of the lobes that have a density,
//! - `pdf(wo, wi)`: the solid-angle density `sample` draws `wi` with, for those lobes,
//! - `sample(wo, u)`: a direction, its weight f · |cos θi| / pdf, and whether it came from a
//!   delta lobe (a smooth mirror or interface), which `eval` and `pdf` never see.
//!
//! GGX as in Walter et al. 2007 with the height-correlated masking-shadowing term, sampled
//! by visible normals (Heitz 2018, "Sampling the GGX Distribution of Visible Normals");
//! dielectric transmission as in pbrt-v4 (radiance scaled by 1/η² when it crosses).
#[cfg(target_arch = "spirv")]
use spirv_std::num_traits::Float;

use crate::glam::Vec3;
use crate::math::{luminance, sqrt, PI};
use crate::sampling::cosine_hemisphere;

/// Lambertian diffuse: albedo / π.
pub const BSDF_DIFFUSE: u32 = 0;
/// GGX conductor, Schlick's Fresnel from the reflectance at normal incidence `specular`.
pub const BSDF_CONDUCTOR: u32 = 1;
/// GGX dielectric interface of relative index `eta`: reflection and transmission.
pub const BSDF_DIELECTRIC: u32 = 2;
/// Diffuse `albedo` under a GGX dielectric coat of index `eta` (white specular).
pub const BSDF_COATED: u32 = 3;

/// GGX α below which a lobe is treated as perfectly smooth (a delta lobe), as pbrt-v4 does:
/// the microfacet formulas lose precision there.
pub const SMOOTH_ALPHA: f32 = 1e-3;

/// A BSDF at one surface point.
#[derive(Copy, Clone, Debug)]
pub struct Bsdf {
    pub kind: u32,
    /// Diffuse albedo (diffuse and coated).
    pub albedo: Vec3,
    /// Conductor reflectance at normal incidence.
    pub specular: Vec3,
    /// GGX α (roughness²).
    pub alpha: f32,
    /// Relative index of refraction across the surface, inside over the side of `wo`
    /// (dielectric: < 1 when leaving the medium; coated: the coat's index).
    pub eta: f32,
}

/// A sampled direction: `weight` = f · |cos θi| / pdf; `pdf` = 0 for delta lobes.
#[derive(Copy, Clone, Debug)]
pub struct BsdfSample {
    pub wi: Vec3,
    pub weight: Vec3,
    pub pdf: f32,
    pub delta: bool,
}

impl BsdfSample {
    /// No direction (absorbed, or a sample below the surface).
    pub fn none() -> Self {
        Self {
            wi: Vec3::Z,
            weight: Vec3::ZERO,
            pdf: 0.0,
            delta: false,
        }
    }
    pub fn is_valid(&self) -> bool {
        self.weight != Vec3::ZERO
    }
}

/// Unpolarised Fresnel reflectance of a dielectric interface for light arriving at cosine
/// `cos_i` (≥ 0) from the side whose relative index across the surface is `eta`.
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0; // total internal reflection
    }
    let cos_t = sqrt(1.0 - sin2_t);
    let parallel = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let perpendicular = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (parallel * parallel + perpendicular * perpendicular)
}

/// Schlick's approximation with reflectance `f0` at normal incidence.
pub fn fresnel_schlick(f0: Vec3, cos_i: f32) -> Vec3 {
    let m = (1.0 - cos_i.clamp(0.0, 1.0)).powi(5);
    f0 + (Vec3::ONE - f0) * m
}

/// GGX normal distribution D(m), for a microfacet normal `m` in the upper hemisphere.
pub fn ggx_d(m: Vec3, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let t = m.z * m.z * (a2 - 1.0) + 1.0;
    a2 / (PI * t * t)
}

/// Smith's Λ(w) for GGX.
fn ggx_lambda(w: Vec3, alpha: f32) -> f32 {
    let cos2 = w.z * w.z;
    if cos2 <= 0.0 {
        return 0.0;
    }
    let tan2 = ((1.0 - cos2) / cos2).max(0.0);
    0.5 * (sqrt(1.0 + alpha * alpha * tan2) - 1.0)
}

pub fn ggx_g1(w: Vec3, alpha: f32) -> f32 {
    1.0 / (1.0 + ggx_lambda(w, alpha))
}

/// Height-correlated masking-shadowing G2(wo, wi).
pub fn ggx_g2(wo: Vec3, wi: Vec3, alpha: f32) -> f32 {
    1.0 / (1.0 + ggx_lambda(wo, alpha) + ggx_lambda(wi, alpha))
}

/// Density of the visible normal `m` seen from `wo`: G1(wo) max(0, wo·m) D(m) / cos θo.
pub fn ggx_visible_pdf(wo: Vec3, m: Vec3, alpha: f32) -> f32 {
    ggx_g1(wo, alpha) * wo.dot(m).max(0.0) * ggx_d(m, alpha) / wo.z
}

/// A microfacet normal visible from `wo` (wo.z > 0), distributed by `ggx_visible_pdf`.
pub fn sample_ggx_visible(wo: Vec3, alpha: f32, u1: f32, u2: f32) -> Vec3 {
    // Stretch to the hemisphere configuration, sample the projected area, unstretch.
    let vh = Vec3::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
    let len2 = vh.x * vh.x + vh.y * vh.y;
    let t1 = if len2 > 0.0 {
        Vec3::new(-vh.y, vh.x, 0.0) / sqrt(len2)
    } else {
        Vec3::X
    };
    let t2 = vh.cross(t1);
    let r = sqrt(u1);
    let phi = 2.0 * PI * u2;
    let p1 = r * phi.cos();
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * sqrt((1.0 - p1 * p1).max(0.0)) + s * r * phi.sin();
    let nh = t1 * p1 + t2 * p2 + vh * sqrt((1.0 - p1 * p1 - p2 * p2).max(0.0));
    Vec3::new(alpha * nh.x, alpha * nh.y, nh.z.max(1e-6)).normalize()
}

fn reflect(wo: Vec3, m: Vec3) -> Vec3 {
    m * (2.0 * wo.dot(m)) - wo
}

/// `wo` refracted through a surface of normal `m` (on wo's side) with relative index
/// `eta`; zero on total internal reflection.
fn refract(wo: Vec3, m: Vec3, eta: f32) -> Vec3 {
    let cos_i = wo.dot(m);
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return Vec3::ZERO;
    }
    let cos_t = sqrt(1.0 - sin2_t);
    -wo / eta + m * (cos_i / eta - cos_t)
}

impl Bsdf {
    pub fn diffuse(albedo: Vec3) -> Self {
        Self {
            kind: BSDF_DIFFUSE,
            albedo,
            specular: Vec3::ZERO,
            alpha: 1.0,
            eta: 1.0,
        }
    }

    /// The one colour a BSDF of its kind reads: a conductor's reflectance, else the
    /// albedo (a dielectric reads neither). What a G-buffer keeps.
    pub fn colour(&self) -> Vec3 {
        if self.kind == BSDF_CONDUCTOR {
            self.specular
        } else {
            self.albedo
        }
    }

    /// A BSDF of `kind` whose `colour` is `colour`.
    pub fn with_colour(kind: u32, colour: Vec3, alpha: f32, eta: f32) -> Self {
        Self {
            kind,
            albedo: colour,
            specular: colour,
            alpha,
            eta,
        }
    }

    fn smooth(&self) -> bool {
        self.alpha < SMOOTH_ALPHA
    }

    /// Whether `sample` picks between lobes with its third number (else it ignores it).
    pub fn chooses_lobes(&self) -> bool {
        self.kind == BSDF_DIELECTRIC || self.kind == BSDF_COATED
    }

    /// Whether every lobe is a delta lobe: next-event estimation cannot help here.
    pub fn is_delta(&self) -> bool {
        (self.kind == BSDF_CONDUCTOR || self.kind == BSDF_DIELECTRIC) && self.smooth()
    }

    /// Probability that the coat samples its specular lobe: its Fresnel reflectance against
    /// the light the diffuse base sends back.
    fn coat_specular_probability(&self, wo: Vec3) -> f32 {
        let f = fresnel_dielectric(wo.z, self.eta);
        let diffuse = (1.0 - f) * luminance(self.albedo);
        (f / (f + diffuse).max(1e-6)).clamp(0.1, 0.9)
    }

    /// f(wo, wi) · |cos θi| of the lobes with a density.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 {
            return Vec3::ZERO;
        }
        if self.kind == BSDF_DIFFUSE {
            if wi.z <= 0.0 {
                return Vec3::ZERO;
            }
            return self.albedo * (wi.z / PI);
        }
        if self.kind == BSDF_CONDUCTOR {
            if self.smooth() || wi.z <= 0.0 {
                return Vec3::ZERO;
            }
            let m = (wo + wi).normalize();
            let f = fresnel_schlick(self.specular, wo.dot(m));
            return f * (ggx_d(m, self.alpha) * ggx_g2(wo, wi, self.alpha) / (4.0 * wo.z));
        }
        if self.kind == BSDF_DIELECTRIC {
            if self.smooth() {
                return Vec3::ZERO;
            }
            return Vec3::splat(self.dielectric_eval(wo, wi));
        }
        // Coated: white GGX coat + the diffuse base, seen through the coat twice.
        if wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let base = self.albedo
            * ((1.0 - fresnel_dielectric(wo.z, self.eta))
                * (1.0 - fresnel_dielectric(wi.z, self.eta))
                * wi.z
                / PI);
        if self.smooth() {
            return base;
        }
        let m = (wo + wi).normalize();
        let coat = fresnel_dielectric(wo.dot(m), self.eta)
            * ggx_d(m, self.alpha)
            * ggx_g2(wo, wi, self.alpha)
            / (4.0 * wo.z);
        base + Vec3::splat(coat)
    }

    /// Rough dielectric f · |cos θi| (pbrt-v4's `DielectricBxDF::f`, wo above).
    fn dielectric_eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        let m = self.dielectric_half_vector(wo, wi);
        if m == Vec3::ZERO {
            return 0.0;
        }
        let reflected = wi.z > 0.0;
        let f = fresnel_dielectric(wo.dot(m), self.eta);
        let dg = ggx_d(m, self.alpha) * ggx_g2(wo, wi, self.alpha);
        if reflected {
            dg * f / (4.0 * wo.z)
        } else {
            let denom = wi.dot(m) + wo.dot(m) / self.eta;
            let denom = denom * denom * wo.z;
            dg * (1.0 - f) * (wi.dot(m) * wo.dot(m) / denom).abs() / (self.eta * self.eta)
        }
    }

    /// The generalised half vector of a rough dielectric pair (upper hemisphere; the pair
    /// is a reflection when wi.z > 0), or zero for pairs no microfacet connects. (A zero
    /// vector rather than an `Option`: rust-gpu cannot return an `Option` of a tuple.)
    fn dielectric_half_vector(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wi.z == 0.0 {
            return Vec3::ZERO;
        }
        let etap = if wi.z > 0.0 { 1.0 } else { self.eta };
        let m = wi * etap + wo;
        if m.length_squared() == 0.0 {
            return Vec3::ZERO;
        }
        let m = m.normalize();
        let m = if m.z < 0.0 { -m } else { m };
        // Microfacets seen from behind contribute nothing.
        if m.dot(wi) * wi.z < 0.0 || m.dot(wo) * wo.z < 0.0 {
            return Vec3::ZERO;
        }
        m
    }

    /// Solid-angle density with which `sample` draws `wi` (lobes with a density only).
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 {
            return 0.0;
        }
        if self.kind == BSDF_DIFFUSE {
            return wi.z.max(0.0) / PI;
        }
        if self.kind == BSDF_CONDUCTOR {
            if self.smooth() || wi.z <= 0.0 {
                return 0.0;
            }
            let m = (wo + wi).normalize();
            return ggx_visible_pdf(wo, m, self.alpha) / (4.0 * wo.dot(m));
        }
        if self.kind == BSDF_DIELECTRIC {
            if self.smooth() {
                return 0.0;
            }
            let m = self.dielectric_half_vector(wo, wi);
            if m == Vec3::ZERO {
                return 0.0;
            }
            let reflected = wi.z > 0.0;
            let r = fresnel_dielectric(wo.dot(m), self.eta);
            let visible = ggx_visible_pdf(wo, m, self.alpha);
            return if reflected {
                visible / (4.0 * wo.dot(m)) * r
            } else {
                let denom = wi.dot(m) + wo.dot(m) / self.eta;
                visible * (wi.dot(m).abs() / (denom * denom)) * (1.0 - r)
            };
        }
        // Coated: the mixture of the coat's and the base's sampling.
        let ps = self.coat_specular_probability(wo);
        let diffuse = (1.0 - ps) * wi.z.max(0.0) / PI;
        if self.smooth() || wi.z <= 0.0 {
            return diffuse;
        }
        let m = (wo + wi).normalize();
        diffuse + ps * ggx_visible_pdf(wo, m, self.alpha) / (4.0 * wo.dot(m))
    }

    /// Draw `wi` from three uniform numbers.
    pub fn sample(&self, wo: Vec3, u1: f32, u2: f32, u3: f32) -> BsdfSample {
        if wo.z <= 0.0 {
            return BsdfSample::none();
        }
        if self.kind == BSDF_DIFFUSE {
            // Cosine sampling cancels cos/π against the BRDF: weight = albedo.
            let wi = cosine_hemisphere(u1, u2);
            return BsdfSample {
                wi,
                weight: self.albedo,
                pdf: wi.z / PI,
                delta: false,
            };
        }
        if self.kind == BSDF_CONDUCTOR {
            if self.smooth() {
                let wi = Vec3::new(-wo.x, -wo.y, wo.z);
                return BsdfSample {
                    wi,
                    weight: fresnel_schlick(self.specular, wo.z),
                    pdf: 0.0,
                    delta: true,
                };
            }
            let m = sample_ggx_visible(wo, self.alpha, u1, u2);
            return self.sampled(wo, reflect(wo, m));
        }
        if self.kind == BSDF_DIELECTRIC {
            return self.sample_dielectric(wo, u1, u2, u3);
        }
        // Coated: the coat's reflection or the diffuse base, by `coat_specular_probability`.
        let ps = self.coat_specular_probability(wo);
        if u3 < ps {
            if self.smooth() {
                let wi = Vec3::new(-wo.x, -wo.y, wo.z);
                return BsdfSample {
                    wi,
                    weight: Vec3::splat(fresnel_dielectric(wo.z, self.eta) / ps),
                    pdf: 0.0,
                    delta: true,
                };
            }
            let m = sample_ggx_visible(wo, self.alpha, u1, u2);
            return self.sampled(wo, reflect(wo, m));
        }
        self.sampled(wo, cosine_hemisphere(u1, u2))
    }

    /// A direction drawn from the lobes with a density: weight = eval / pdf.
    fn sampled(&self, wo: Vec3, wi: Vec3) -> BsdfSample {
        let pdf = self.pdf(wo, wi);
        if pdf.is_nan() || pdf <= 0.0 {
            return BsdfSample::none();
        }
        BsdfSample {
            wi,
            weight: self.eval(wo, wi) / pdf,
            pdf,
            delta: false,
        }
    }

    fn sample_dielectric(&self, wo: Vec3, u1: f32, u2: f32, u3: f32) -> BsdfSample {
        if self.smooth() {
            // Reflect with probability F, else refract: each weight is then 1 (1/η² across).
            let r = fresnel_dielectric(wo.z, self.eta);
            if u3 < r {
                return BsdfSample {
                    wi: Vec3::new(-wo.x, -wo.y, wo.z),
                    weight: Vec3::ONE,
                    pdf: 0.0,
                    delta: true,
                };
            }
            let wi = refract(wo, Vec3::Z, self.eta);
            if wi == Vec3::ZERO {
                return BsdfSample::none();
            }
            return BsdfSample {
                wi,
                weight: Vec3::splat(1.0 / (self.eta * self.eta)),
                pdf: 0.0,
                delta: true,
            };
        }
        let m = sample_ggx_visible(wo, self.alpha, u1, u2);
        let r = fresnel_dielectric(wo.dot(m), self.eta);
        let reflected = u3 < r;
        let wi = if reflected {
            reflect(wo, m)
        } else {
            refract(wo, m, self.eta)
        };
        // A reflection must stay above the surface and a refraction go below it: off a
        // steep microfacet either can end on the wrong side, and is then lost.
        if (wi.z > 0.0) != reflected || wi.z == 0.0 {
            return BsdfSample::none();
        }
        self.sampled(wo, wi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    fn dir(theta_deg: f32, phi_deg: f32) -> Vec3 {
        let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
        Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
    }

    fn family() -> [Bsdf; 9] {
        let bsdf = |kind, alpha, eta| Bsdf {
            kind,
            albedo: Vec3::new(0.9, 0.6, 0.3),
            specular: Vec3::new(0.95, 0.8, 0.5),
            alpha,
            eta,
        };
        [
            Bsdf::diffuse(Vec3::splat(0.7)),
            bsdf(BSDF_CONDUCTOR, 0.05, 1.0),
            bsdf(BSDF_CONDUCTOR, 0.3, 1.0),
            bsdf(BSDF_CONDUCTOR, 1.0, 1.0),
            bsdf(BSDF_DIELECTRIC, 0.1, 1.5),
            bsdf(BSDF_DIELECTRIC, 0.5, 1.0 / 1.5),
            bsdf(BSDF_DIELECTRIC, 0.3, 1.33),
            bsdf(BSDF_COATED, 0.1, 1.5),
            bsdf(BSDF_COATED, 0.6, 1.5),
        ]
    }

    /// Monte Carlo estimates of the directional albedo ∫ f |cos θi| dωi from `wo` (first
    /// channel), by sampling (the weights) and, independently, by uniform sphere sampling
    /// of `eval`, each with its standard error.
    fn albedos(b: &Bsdf, wo: Vec3, n: u32) -> ((f64, f64), (f64, f64)) {
        let mut rng = Rng::from_seed(17);
        let mut sums = [0f64; 4];
        for _ in 0..n {
            let s = b.sample(wo, rng.next_f32(), rng.next_f32(), rng.next_f32());
            let w = s.weight.x as f64;
            sums[0] += w;
            sums[1] += w * w;
            let z = 1.0 - 2.0 * rng.next_f32();
            let phi = 2.0 * PI * rng.next_f32();
            let r = (1.0 - z * z).max(0.0).sqrt();
            let wi = Vec3::new(r * phi.cos(), r * phi.sin(), z);
            let e = (b.eval(wo, wi).x * 4.0 * PI) as f64;
            sums[2] += e;
            sums[3] += e * e;
        }
        let n = n as f64;
        let mean_se = |s: f64, s2: f64| {
            let mean = s / n;
            (mean, ((s2 / n - mean * mean).max(0.0) / n).sqrt())
        };
        (mean_se(sums[0], sums[1]), mean_se(sums[2], sums[3]))
    }

    #[test]
    fn no_lobe_creates_energy_and_sampling_agrees_with_eval() {
        // White furnace per direction: the albedo is at most 1 (1/η² aside: transmission
        // into a denser medium concentrates radiance, so dielectrics are checked with
        // their η² factor undone), and the sampling weights estimate the same integral as
        // eval / uniform pdf.
        for b in family() {
            for theta in [0.0f32, 30.0, 60.0, 85.0] {
                let wo = dir(theta, 20.0);
                let ((s, s_se), (e, e_se)) = albedos(&b, wo, 400_000);
                let crossing = if b.kind == BSDF_DIELECTRIC {
                    1.0 / (b.eta * b.eta)
                } else {
                    1.0
                };
                let bound = crossing.max(1.0) as f64;
                assert!(
                    s <= bound + 5.0 * s_se,
                    "{b:?} θ {theta}: albedo {s} ± {s_se} by sampling"
                );
                // Both estimate one integral: within 5 standard errors (uniform sampling
                // of a narrow lobe is heavy-tailed, which its standard error shows).
                assert!(
                    (s - e).abs() <= 5.0 * (s_se + e_se) + 1e-3,
                    "{b:?} θ {theta}: sampling {s} ± {s_se} vs eval {e} ± {e_se}"
                );
            }
        }
    }

    #[test]
    fn smooth_dielectric_reflects_fresnel_and_transmits_the_rest() {
        let b = Bsdf {
            kind: BSDF_DIELECTRIC,
            albedo: Vec3::ONE,
            specular: Vec3::ONE,
            alpha: 0.0,
            eta: 1.5,
        };
        // Normal incidence: F = ((1 - 1.5) / (1 + 1.5))² = 0.04.
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        let wo = dir(40.0, 0.0);
        let f = fresnel_dielectric(wo.z, 1.5);
        let mut rng = Rng::from_seed(3);
        let (mut reflected, n) = (0u32, 200_000u32);
        for _ in 0..n {
            let s = b.sample(wo, rng.next_f32(), rng.next_f32(), rng.next_f32());
            assert!(s.delta);
            if s.wi.z > 0.0 {
                reflected += 1;
            } else {
                // Snell: sin θt = sin θi / η.
                let sin_t = (1.0 - s.wi.z * s.wi.z).sqrt();
                assert!((sin_t - 40f32.to_radians().sin() / 1.5).abs() < 1e-5);
            }
        }
        let frac = reflected as f32 / n as f32;
        assert!(
            (frac - f).abs() < 5.0 * (f * (1.0 - f) / n as f32).sqrt(),
            "{frac} vs F {f}"
        );
        // Total internal reflection from inside beyond the critical angle (41.8° for 1.5).
        assert_eq!(fresnel_dielectric(dir(45.0, 0.0).z, 1.0 / 1.5), 1.0);
    }

    #[test]
    fn reflection_lobes_are_reciprocal() {
        for b in family() {
            if b.kind == BSDF_DIELECTRIC {
                continue; // transmission is reciprocal only up to η²
            }
            for (a, c) in [
                (dir(20.0, 10.0), dir(50.0, 200.0)),
                (dir(70.0, 0.0), dir(10.0, 90.0)),
            ] {
                let fa = b.eval(a, c) / c.z;
                let fc = b.eval(c, a) / a.z;
                assert!(
                    (fa - fc).abs().max_element() <= 1e-4 * fa.max_element().max(1e-3),
                    "{b:?}: f({a}, {c}) = {fa} vs {fc}"
                );
            }
        }
    }

    #[test]
    fn samplers_follow_their_pdfs() {
        // χ² of sampled directions against pdf() integrated over a grid of
        // (cos θ, φ) cells on the sphere, for every lobe with a density.
        const CELLS_Z: usize = 16;
        const CELLS_PHI: usize = 32;
        const N: u32 = 400_000;
        for b in family() {
            let wo = dir(35.0, 0.0);
            let mut rng = Rng::from_seed(11);
            let mut observed = [0u64; CELLS_Z * CELLS_PHI];
            let cell = |w: Vec3| {
                let iz = (((w.z + 1.0) * 0.5 * CELLS_Z as f32) as usize).min(CELLS_Z - 1);
                let phi = w.y.atan2(w.x).rem_euclid(2.0 * PI);
                let ip = ((phi / (2.0 * PI) * CELLS_PHI as f32) as usize).min(CELLS_PHI - 1);
                iz * CELLS_PHI + ip
            };
            let mut valid = 0u64;
            for _ in 0..N {
                let s = b.sample(wo, rng.next_f32(), rng.next_f32(), rng.next_f32());
                if s.is_valid() {
                    observed[cell(s.wi)] += 1;
                    valid += 1;
                }
            }
            // Expected counts: N × ∫cell pdf, by a fine midpoint rule in (z, φ).
            const SUB: usize = 12;
            let mut expected = [0f64; CELLS_Z * CELLS_PHI];
            for iz in 0..CELLS_Z * SUB {
                let z = -1.0 + (iz as f32 + 0.5) * 2.0 / (CELLS_Z * SUB) as f32;
                for ip in 0..CELLS_PHI * SUB {
                    let phi = (ip as f32 + 0.5) * 2.0 * PI / (CELLS_PHI * SUB) as f32;
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    let wi = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                    let area = (2.0 / (CELLS_Z * SUB) as f64)
                        * (2.0 * PI as f64 / (CELLS_PHI * SUB) as f64);
                    expected[cell(wi)] += b.pdf(wo, wi) as f64 * area * N as f64;
                }
            }
            // The pdf integrates to the fraction of samples that are valid.
            let total: f64 = expected.iter().sum();
            assert!(
                (total - valid as f64).abs() <= 0.01 * N as f64,
                "{b:?}: ∫pdf·N = {total}, valid samples {valid}"
            );
            // Pool sparse cells (expected < 5) into one, then χ².
            let (mut chi2, mut dof, mut pool_o, mut pool_e) = (0.0, 0usize, 0.0, 0.0);
            for (o, e) in observed.iter().zip(&expected) {
                if *e < 5.0 {
                    pool_o += *o as f64;
                    pool_e += e;
                } else {
                    chi2 += (*o as f64 - e).powi(2) / e;
                    dof += 1;
                }
            }
            if pool_e >= 5.0 {
                chi2 += (pool_o - pool_e).powi(2) / pool_e;
                dof += 1;
            }
            // Wilson–Hilferty critical value at significance 1e-4; the midpoint rule's own
            // error in steep cells is allowed for by a 1.5x margin.
            let k = (dof - 1) as f64;
            let critical = k * (1.0 - 2.0 / (9.0 * k) + 3.719 * (2.0 / (9.0 * k)).sqrt()).powi(3);
            assert!(
                chi2 <= 1.5 * critical,
                "{b:?}: χ² {chi2:.1} > {critical:.1} ({dof} cells)"
            );
        }
    }
}
