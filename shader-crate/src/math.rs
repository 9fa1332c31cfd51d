//! Small float helpers that behave the same on the CPU and in SPIR-V.
#[cfg(target_arch = "spirv")]
use spirv_std::num_traits::Float;

use crate::glam::Vec3;

pub const PI: f32 = core::f32::consts::PI;

pub fn vec3(a: [f32; 3]) -> Vec3 {
    Vec3::new(a[0], a[1], a[2])
}

pub fn sqrt(x: f32) -> f32 {
    x.sqrt()
}

pub fn sin_cos(x: f32) -> (f32, f32) {
    (x.sin(), x.cos())
}

/// The larger of `a` and `b`, the other where one is NaN: `f32::max`. rust-gpu writes
/// `f32::max` as compares, selects and a branch on NaN; GLSL's NMax is the same function
/// in one instruction.
#[inline(always)]
pub fn max(a: f32, b: f32) -> f32 {
    #[cfg(target_arch = "spirv")]
    return glsl!(f32, "80", a, b); // NMax
    #[cfg(not(target_arch = "spirv"))]
    a.max(b)
}

/// The smaller of `a` and `b`, the other where one is NaN: `f32::min` (GLSL's NMin).
#[inline(always)]
pub fn min(a: f32, b: f32) -> f32 {
    #[cfg(target_arch = "spirv")]
    return glsl!(f32, "79", a, b); // NMin
    #[cfg(not(target_arch = "spirv"))]
    a.min(b)
}

/// GLSL.std.450 instruction number `op` on the variables given, its result a `ty`: one
/// instruction where rust-gpu would write the Rust function as several (`max`, `min`,
/// `bits::first_bit_high`).
#[cfg(target_arch = "spirv")]
macro_rules! glsl {
    ($ty:ty, $op:literal, $($x:ident),+) => {{
        let mut result = <$ty>::default();
        // SAFETY: one arithmetic instruction on the operands, its result stored to a local.
        unsafe {
            core::arch::asm!(
                "%glsl = OpExtInstImport \"GLSL.std.450\"",
                concat!("%result = OpExtInst typeof*{result} %glsl ", $op $(, " {", stringify!($x), "}")+),
                "OpStore {result} %result",
                $($x = in(reg) $x,)+
                result = in(reg) &mut result,
            );
        }
        result
    }};
}
#[cfg(target_arch = "spirv")]
pub(crate) use glsl;

/// Division of whole numbers below `FAST_DIVIDENDS` by a fixed divisor through a float
/// reciprocal: ⌊(n + ½) · (1/d)⌋ is ⌊n / d⌋ exactly there, as (n + ½)/d lies at least ½/d
/// from a whole number and the float error stays below 0.36/d (n + ½ exact, the product
/// rounded once, the reciprocal within the 2.5 ulp that Vulkan's division promises). It
/// costs a multiply where an integer division is a long instruction sequence on the GPU:
/// the AO pool's and strata's divisions per ray this way made AO 1.0–1.7% faster on the
/// H200 (docs/PERFORMANCE.md, "Benchmark suite"). Larger dividends divide as integers.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Divisor {
    d: u32,
    inv: f32,
}

/// Dividends below this divide through the reciprocal (see `Divisor`).
pub const FAST_DIVIDENDS: u32 = 1 << 21;

impl Divisor {
    /// Division by 1.
    pub const ONE: Divisor = Divisor { d: 1, inv: 1.0 };

    /// Division by `d` (> 0).
    pub fn new(d: u32) -> Self {
        Self {
            d,
            inv: 1.0 / d as f32,
        }
    }

    /// (⌊n / d⌋, n mod d).
    #[inline(always)]
    pub fn div_rem(&self, n: u32) -> (u32, u32) {
        if n < FAST_DIVIDENDS {
            let q = ((n as f32 + 0.5) * self.inv) as u32;
            (q, n - q * self.d)
        } else {
            div_rem(n, self.d) // d > 0 (`new`)
        }
    }
}

/// (⌊n / d⌋, n mod d) for d > 0, the callers' invariant, without the division-by-zero
/// check of `/` and `%`: a panic, which rust-gpu makes a return from the kernel that every
/// loop around it pays for (`types::load`). (d = 0 would give (0, n).)
#[inline(always)]
pub fn div_rem(n: u32, d: u32) -> (u32, u32) {
    let q = n.checked_div(d).unwrap_or(0);
    (q, n - q * d)
}

/// Largest component index of `|v|` (0, 1 or 2).
pub fn max_dimension(v: Vec3) -> u32 {
    if v.x >= v.y && v.x >= v.z {
        0
    } else if v.y >= v.z {
        1
    } else {
        2
    }
}

/// `v[i]` for a run-time index without dynamic vector indexing in SPIR-V.
pub fn component(v: Vec3, i: u32) -> f32 {
    if i == 0 {
        v.x
    } else if i == 1 {
        v.y
    } else {
        v.z
    }
}

/// Relative luminance of linear Rec. 709 / sRGB primaries (ITU-R BT.709 weights): the
/// scalar that light power, RIS targets and tone mapping use.
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

pub fn tan(x: f32) -> f32 {
    x.tan()
}

/// The high 32 bits of the 64-bit product `a · b`, in 32-bit arithmetic (SPIR-V without
/// the Int64 capability): maps a uniform 32-bit number onto `0..b` without modulo bias.
pub fn mul_hi(a: u32, b: u32) -> u32 {
    let (a_lo, a_hi) = (a & 0xffff, a >> 16);
    let (b_lo, b_hi) = (b & 0xffff, b >> 16);
    let lo_lo = a_lo * b_lo;
    let hi_lo = a_hi * b_lo;
    let lo_hi = a_lo * b_hi;
    // Cannot overflow: lo_hi ≤ (2¹⁶−1)², the other two terms < 2¹⁶ each.
    let middle = (lo_lo >> 16) + (hi_lo & 0xffff) + lo_hi;
    a_hi * b_hi + (hi_lo >> 16) + (middle >> 16)
}

#[cfg(test)]
mod tests {
    #[test]
    fn mul_hi_is_the_high_word_of_the_product() {
        let mut x = 0x1234_5678u32;
        for _ in 0..100_000 {
            x = crate::rng::pcg_hash(x);
            let y = crate::rng::pcg_hash(x ^ 0x5bd1_e995);
            assert_eq!(
                super::mul_hi(x, y),
                ((x as u64 * y as u64) >> 32) as u32,
                "{x} {y}"
            );
        }
        assert_eq!(super::mul_hi(u32::MAX, u32::MAX), u32::MAX - 1);
        assert_eq!(super::mul_hi(u32::MAX, 7), 6);
    }

    #[test]
    fn divides_exactly_below_the_fast_bound_and_above() {
        for d in [1u32, 2, 3, 5, 7, 8, 9, 13, 64, 100, 127, 128, 1000, 4097] {
            let div = super::Divisor::new(d);
            let mut n = 0u32;
            while n < super::FAST_DIVIDENDS {
                assert_eq!(div.div_rem(n), (n / d, n % d), "{n} / {d}");
                n += 1 + n / 4096;
            }
            for n in [
                super::FAST_DIVIDENDS - 1,
                super::FAST_DIVIDENDS,
                u32::MAX - 1,
                u32::MAX,
            ] {
                assert_eq!(div.div_rem(n), (n / d, n % d), "{n} / {d}");
                assert_eq!(super::div_rem(n, d), (n / d, n % d), "{n} / {d}");
            }
        }
    }
}
