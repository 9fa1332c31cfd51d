//! Bit operations of the traversal's hit masks, as single GPU instructions. Rust's `<<`
//! and `>>` wrap a variable shift amount to 0..31, which rust-gpu writes out as an AND
//! before every such shift, and `leading_zeros` handles 0 with a compare and a select;
//! the walk's bit indices are below 32 and its masks non-zero by construction, so these
//! leave both out.

/// Index of the highest set bit of `x` (x ≠ 0): GLSL's FindUMsb, one instruction.
#[inline(always)]
pub fn first_bit_high(x: u32) -> u32 {
    debug_assert!(x != 0);
    #[cfg(target_arch = "spirv")]
    return crate::math::glsl!(u32, "75", x); // FindUMsb
    #[cfg(not(target_arch = "spirv"))]
    {
        31 - x.leading_zeros()
    }
}

/// `x << k` for k < 32.
#[inline(always)]
pub fn shl(x: u32, k: u32) -> u32 {
    debug_assert!(k < 32);
    // SAFETY: k < 32, the callers' bit indices.
    unsafe { x.unchecked_shl(k) }
}

/// `x >> k` for k < 32.
#[inline(always)]
pub fn shr(x: u32, k: u32) -> u32 {
    debug_assert!(k < 32);
    // SAFETY: k < 32, the callers' bit indices.
    unsafe { x.unchecked_shr(k) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn as_the_operators() {
        for k in 0..32 {
            assert_eq!(first_bit_high(1 << k), k);
            assert_eq!(first_bit_high((1 << k) | 1), k);
            assert_eq!(first_bit_high(u32::MAX >> (31 - k)), k);
            for x in [1u32, 0x8000_0001, 0xdead_beef, u32::MAX] {
                assert_eq!(shl(x, k), x << k);
                assert_eq!(shr(x, k), x >> k);
            }
        }
    }
}
