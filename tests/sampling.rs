//! χ² goodness-of-fit tests for the samplers the integrators rely on.
mod common;

use common::{chi_square, chi_square_critical};
use glam::Vec3;
use kernels::lights::{select_light, selection_pdf};
use kernels::rng::Rng;
use kernels::sampling::{cosine_hemisphere, uniform_triangle};
use kernels::types::{Material, Triangle, LIGHT_SAMPLING_POWER, LIGHT_SAMPLING_UNIFORM};
use runner::lights::build_light_table;

#[test]
fn cosine_hemisphere_matches_cos_theta_over_pi() {
    // Bins in (θ, φ); a bin's probability is ∫∫ cos θ sin θ / π dθ dφ
    // = (sin² θ1 − sin² θ0) / 2 · (φ1 − φ0) / π.
    let (nt, np, n) = (12usize, 24usize, 1_000_000u64);
    let mut counts = vec![0u64; nt * np];
    let mut rng = Rng::from_seed(11);
    for _ in 0..n {
        let d = cosine_hemisphere(rng.next_f32(), rng.next_f32());
        let theta = d.z.clamp(-1.0, 1.0).acos();
        let phi = d.y.atan2(d.x).rem_euclid(2.0 * std::f32::consts::PI);
        let i = ((theta / std::f32::consts::FRAC_PI_2 * nt as f32) as usize).min(nt - 1);
        let j = ((phi / (2.0 * std::f32::consts::PI) * np as f32) as usize).min(np - 1);
        counts[i * np + j] += 1;
    }
    let mut expected = vec![0.0; nt * np];
    for i in 0..nt {
        let (t0, t1) = (
            i as f64 / nt as f64 * std::f64::consts::FRAC_PI_2,
            (i + 1) as f64 / nt as f64 * std::f64::consts::FRAC_PI_2,
        );
        let p_theta = (t1.sin().powi(2) - t0.sin().powi(2)) / 2.0;
        for j in 0..np {
            expected[i * np + j] = n as f64 * p_theta * (2.0 / np as f64);
        }
    }
    let chi2 = chi_square(&counts, &expected);
    let crit = chi_square_critical(nt * np - 1);
    assert!(chi2 < crit, "χ² = {chi2:.1} ≥ {crit:.1}");
}

#[test]
fn triangle_sampler_is_uniform_in_area() {
    // Subdivide the triangle into k² congruent sub-triangles (equal areas) and count hits.
    let k = 16usize;
    let n = 1_000_000u64;
    let mut counts = vec![0u64; k * k];
    let mut rng = Rng::from_seed(12);
    for _ in 0..n {
        let (b1, b2) = uniform_triangle(rng.next_f32(), rng.next_f32());
        counts[sub_triangle(b1, b2, k)] += 1;
    }
    let expected = vec![n as f64 / (k * k) as f64; k * k];
    let chi2 = chi_square(&counts, &expected);
    let crit = chi_square_critical(k * k - 1);
    assert!(chi2 < crit, "χ² = {chi2:.1} ≥ {crit:.1}");
}

/// Index in 0..k² of the sub-triangle containing barycentrics (b1, b2) when the triangle
/// is cut by the lines b1 = i/k, b2 = j/k and b1 + b2 = m/k.
fn sub_triangle(b1: f32, b2: f32, k: usize) -> usize {
    let (x, y) = (b1 * k as f32, b2 * k as f32);
    let i = (x.floor() as usize).min(k - 1);
    let j = (y.floor() as usize).min(k - 1 - i);
    let upper = (x - i as f32) + (y - j as f32) > 1.0 && i + j < k - 1;
    // Row j has (k − j) lower and (k − j − 1) upper triangles: 2(k − j) − 1 in all.
    let row_start: usize = (0..j).map(|r| 2 * (k - r) - 1).sum();
    row_start + 2 * i + upper as usize
}

#[test]
fn light_selection_follows_power_and_uniform_pdfs() {
    // 50 emitters with very different powers (area × luminance of Ke).
    let mut rng = Rng::from_seed(13);
    let mut materials = vec![Material::new(Vec3::splat(0.5), Vec3::ZERO)];
    let mut tris = vec![Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y, 0)];
    for i in 0..50 {
        let strength = 0.1 + 100.0 * rng.next_f32().powi(3);
        materials.push(Material::new(
            Vec3::splat(0.5),
            Vec3::new(strength, 0.5 * strength, 0.2),
        ));
        let s = 0.1 + rng.next_f32();
        let o = Vec3::new(i as f32, 0.0, 0.0);
        tris.push(Triangle::new(o, o + Vec3::X * s, o + Vec3::Y * s, i + 1));
    }
    let order: Vec<u32> = (0..tris.len() as u32).collect();
    let lights = build_light_table(&mut tris, &order, &materials, &Default::default());
    assert_eq!(lights.len(), 50);
    let total: f32 = lights.iter().map(|l| l.pdf).sum();
    assert!((total - 1.0).abs() < 1e-5);
    for mode in [LIGHT_SAMPLING_POWER, LIGHT_SAMPLING_UNIFORM] {
        let n = 2_000_000u64;
        let mut counts = vec![0u64; lights.len()];
        for _ in 0..n {
            counts[select_light(&lights, mode, rng.next_u32(), rng.next_f32()) as usize] += 1;
        }
        let expected: Vec<f64> = (0..lights.len() as u32)
            .map(|i| n as f64 * selection_pdf(&lights, mode, i) as f64)
            .collect();
        // Pool bins with tiny expectations so χ² stays valid.
        let (mut o2, mut e2, mut acc) = (Vec::new(), Vec::new(), (0u64, 0.0f64));
        for (o, e) in counts.iter().zip(&expected) {
            acc = (acc.0 + o, acc.1 + e);
            if acc.1 >= 20.0 {
                o2.push(acc.0);
                e2.push(acc.1);
                acc = (0, 0.0);
            }
        }
        let chi2 = chi_square(&o2, &e2);
        let crit = chi_square_critical(o2.len() - 1);
        assert!(chi2 < crit, "mode {mode}: χ² = {chi2:.1} ≥ {crit:.1}");
    }
    // Each emitter knows its table slot.
    for (i, l) in lights.iter().enumerate() {
        assert_eq!(tris[l.triangle as usize].light, i as u32);
    }
}

/// With 2¹⁸ lights, the probability with which `select_light` picks each light — worked out
/// exactly from the 2³² slot numbers and 2²⁴ coin values it can draw — must be the pdf the
/// integrators divide by. (One 24-bit number for slot and coin gave the coin 6 bits here.)
#[test]
fn light_selection_is_exact_for_many_lights() {
    let n = 1usize << 18;
    let mut rng = Rng::from_seed(29);
    let mut materials = vec![Material::new(Vec3::splat(0.5), Vec3::ZERO)];
    let mut tris = Vec::with_capacity(n);
    for i in 0..n {
        // Powers over six orders of magnitude.
        let strength = 10f32.powf(6.0 * rng.next_f32() - 3.0);
        materials.push(Material::new(Vec3::splat(0.5), Vec3::splat(strength)));
        let o = Vec3::new(i as f32, 0.0, 0.0);
        tris.push(Triangle::new(o, o + Vec3::X, o + Vec3::Y, i as u32 + 1));
    }
    let order: Vec<u32> = (0..tris.len() as u32).collect();
    let lights = build_light_table(&mut tris, &order, &materials, &Default::default());
    assert_eq!(lights.len(), n);
    let two32 = 2f64.powi(32);
    let two24 = 2f64.powi(24);
    // Slot s gets the u with ⌊u·n / 2³²⌋ = s; the coin takes the values j / 2²⁴.
    let slot_p = |s: usize| {
        ((((s + 1) as f64) * two32 / n as f64).ceil() - ((s as f64) * two32 / n as f64).ceil())
            / two32
    };
    let coin_below = |t: f32| ((t as f64 * two24).ceil().clamp(0.0, two24)) / two24;
    let mut picked = vec![0f64; n];
    let mut aliased_by = vec![0u32; n];
    for (s, l) in lights.iter().enumerate() {
        let q = coin_below(l.threshold);
        picked[s] += slot_p(s) * q;
        picked[l.alias as usize] += slot_p(s) * (1.0 - q);
        aliased_by[l.alias as usize] += 1;
    }
    // Exact but for the coin's 2⁻²⁴ steps (one per slot that can land on the light), the
    // ±1 count of slot sizes and f32 rounding of thresholds and pdfs.
    let mut worst = 0.0f64;
    for i in 0..n {
        let pdf = selection_pdf(&lights, LIGHT_SAMPLING_POWER, i as u32) as f64;
        let tolerance = 1e-4 * pdf + (1 + aliased_by[i]) as f64 / (two24 * n as f64);
        let err = (picked[i] - pdf).abs();
        worst = worst.max(err / tolerance);
        assert!(
            err <= tolerance,
            "light {i}: picked with {} but pdf {pdf}",
            picked[i]
        );
    }
    eprintln!("worst error / tolerance: {worst:.3}");
    // And the uniform mode: every slot equally likely to within one u32 value.
    for s in [0, 1, n / 3, n - 1] {
        assert!((slot_p(s) * n as f64 - 1.0).abs() < 2.0 * n as f64 / two32);
        assert_eq!(
            select_light(
                &lights,
                LIGHT_SAMPLING_UNIFORM,
                ((s as f64 + 0.5) * two32 / n as f64) as u32,
                0.0
            ),
            s as u32
        );
    }
}
