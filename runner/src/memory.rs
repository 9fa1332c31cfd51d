//! Refusing work that cannot fit in memory before allocating it: one error line with the
//! numbers, instead of an abort ("memory allocation of N bytes failed") or a panic deep in
//! a dependency.
use crate::bail;
use crate::error::Result;

/// Peak bytes per triangle of building and rendering a scene (triangles, their leaf-ordered
/// copy, obvhs's build, BVH nodes, light table): rocks-1m (998,404 triangles) peaked at
/// 347 MB with the GPU's tree on the CPU backend (`bench --backend cpu --bvh-quality fast`,
/// the maximum resident size, before `--backend cpu` got a tree of its own: 340 MB, as
/// its leaves of up to 3 make fewer nodes). Measured with PLOC's build; `check_scene`
/// scales it for the SBVH's.
pub const BYTES_PER_SCENE_TRIANGLE: u64 = 360;
/// Peak bytes per byte of an OBJ file while it is read and built (text, tobj's arrays, the
/// scene): a 122 MB OBJ of rocks-1m peaked at 623 MB.
pub const BYTES_PER_OBJ_BYTE: f64 = 5.2;

/// Bytes this process may still allocate: the smaller of the system's available memory
/// (`MemAvailable`) and what the address-space and data limits (`ulimit -v`, `ulimit -d`)
/// leave above what the process already maps. None where none of these can be read.
pub fn available_bytes() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok();
    let mem_available = meminfo.as_deref().and_then(|text| {
        let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
        line.split_whitespace()
            .nth(1)?
            .parse::<u64>()
            .ok()
            .map(|kb| kb * 1024)
    });
    let mapped = std::fs::read_to_string("/proc/self/statm")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<u64>().ok())
        .map(|pages| pages * page_size())
        .unwrap_or(0);
    let mut available = mem_available;
    for resource in [libc::RLIMIT_AS, libc::RLIMIT_DATA] {
        let mut limit = libc::rlimit {
            rlim_cur: 0,
            rlim_max: 0,
        };
        // SAFETY: getrlimit writes the struct we pass and nothing else.
        let ok = unsafe { libc::getrlimit(resource, &mut limit) } == 0;
        if ok && limit.rlim_cur != libc::RLIM_INFINITY {
            let left = limit.rlim_cur.saturating_sub(mapped);
            available = Some(available.map_or(left, |a| a.min(left)));
        }
    }
    available
}

fn page_size() -> u64 {
    // SAFETY: sysconf has no preconditions.
    let size = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
    if size > 0 {
        size as u64
    } else {
        4096
    }
}

/// How much more a build at `--bvh-quality high` (the SBVH: its references, their parts'
/// copies while a node is partitioned, the refined tree) peaks at than PLOC's: rocks-1m
/// and city-1m 511 and 502 MB against 348 and 349 MB.
const SBVH_PEAK_FACTOR: f64 = 1.5;

/// `check` for loading scene `what`, whose peak with PLOC's build is estimated at
/// `bytes`: scaled for the build of the quality chosen (`accel::quality`). (`auto` builds
/// the SBVH too, but only up to 100k triangles: 16 MB more at most, not worth a factor.)
pub fn check_scene(what: &str, bytes: f64) -> Result<()> {
    let factor = if crate::accel::quality() == crate::accel::BvhQuality::High {
        SBVH_PEAK_FACTOR
    } else {
        1.0
    };
    check(what, (bytes * factor) as u64)
}

/// Fail with the numbers if `what` needs more than the memory available.
pub fn check(what: &str, bytes: u64) -> Result<()> {
    if let Some(available) = available_bytes() {
        if bytes > available {
            bail!(
                "{what} needs about {:.1} GB of memory, but only {:.1} GB is available to this process",
                bytes as f64 / 1e9,
                available as f64 / 1e9
            );
        }
    }
    Ok(())
}
