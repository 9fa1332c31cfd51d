//! Votes across a subgroup (a GPU warp: the threads that run in lockstep). On the CPU a
//! thread is a subgroup of one, and every vote is its own. Call these where every thread
//! of the subgroup that is still running reaches them (not under a branch that some take).

/// How many threads of this subgroup `predicate` holds for.
#[inline(always)]
pub fn count(predicate: bool) -> u32 {
    #[cfg(target_arch = "spirv")]
    {
        use spirv_std::arch::{subgroup_ballot, subgroup_ballot_bit_count};
        subgroup_ballot_bit_count(subgroup_ballot(predicate))
    }
    #[cfg(not(target_arch = "spirv"))]
    {
        predicate as u32
    }
}
