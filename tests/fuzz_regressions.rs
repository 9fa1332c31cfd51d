//! The scene loader under hostile input, in CI: every input the fuzzer ever crashed on
//! (tests/fuzz/regressions/), and a bounded, deterministic mutation run over valid scenes.
//! `load_and_render_bytes` may return errors; it must never panic.
use std::panic::catch_unwind;

use kernels::rng::Rng;
use runner::fuzz::load_and_render_bytes;

fn survives(data: &[u8]) -> bool {
    catch_unwind(|| {
        let _ = load_and_render_bytes(data);
    })
    .is_ok()
}

#[test]
fn regression_inputs_do_not_panic() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fuzz/regressions");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let data = std::fs::read(&path).unwrap();
        assert!(survives(&data), "{} panics", path.display());
        n += 1;
    }
    assert!(n > 0, "no regression inputs in {}", dir.display());
}

/// `rounds` random mutations of `seed` (bytes changed, `tokens` inserted, runs cut out or
/// repeated), each of which must not panic.
fn mutations_survive(seed: &[u8], tokens: &[&[u8]], rounds: u32, rng_seed: u32) {
    if let Err(e) = load_and_render_bytes(seed) {
        panic!("the seed itself does not render: {e}");
    }
    let mut rng = Rng::from_seed(rng_seed);
    for round in 0..rounds {
        let mut data = seed.to_vec();
        for _ in 0..1 + rng.next_u32() % 8 {
            let at = (rng.next_u32() as usize) % data.len();
            match rng.next_u32() % 4 {
                0 => data[at] = rng.next_u32() as u8,
                1 => {
                    let t = tokens[(rng.next_u32() % tokens.len() as u32) as usize];
                    data.splice(at..at, t.iter().copied());
                }
                2 => {
                    let end = (at + 1 + rng.next_u32() as usize % 40).min(data.len());
                    data.drain(at..end);
                }
                _ => {
                    let len = (rng.next_u32() as usize % 200).min(data.len() - at);
                    let chunk = data[at..at + len].to_vec();
                    data.splice(at..at, chunk);
                }
            }
        }
        assert!(
            survives(&data),
            "round {round}: input panics:\n{}",
            String::from_utf8_lossy(&data)
        );
    }
}

#[test]
fn mutated_scenes_do_not_panic() {
    let mut seed = runner::scene::CORNELL_BOX_OBJ.as_bytes().to_vec();
    seed.push(0xff);
    seed.extend_from_slice(b"newmtl white\nKd 0.7 0.7 0.7\nnewmtl light\nKe 10 10 10\n");
    let tokens: [&[u8]; 12] = [
        b"nan",
        b"-1",
        b"0",
        b"1e38",
        b"f ",
        b"v ",
        b"\n",
        b"/",
        b"99999",
        b"usemtl light\n",
        b"inf",
        b" ",
    ];
    mutations_survive(&seed, &tokens, 300, 77);
}

#[test]
fn mutated_ply_files_do_not_panic() {
    // A floor with normals and vertex colours (bytes), ASCII.
    let seed = b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
property float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty uchar red\n\
property uchar green\nproperty uchar blue\nelement face 1\nproperty list uchar int vertex_indices\n\
end_header\n-1 0 -1 0 1 0 255 128 0\n-1 0 1 0 1 0 255 128 0\n1 0 1 0 1 0 0 0 255\n\
1 0 -1 0 1 0 0 0 255\n4 0 1 2 3\n";
    let tokens: [&[u8]; 12] = [
        b"nan",
        b"-1",
        b"0",
        b"1e38",
        b"property float red\n",
        b"property uchar blue\n",
        b"\n",
        b"element vertex 9\n",
        b"99999",
        b"property list uchar int vertex_indices\n",
        b"inf",
        b" ",
    ];
    mutations_survive(seed, &tokens, 300, 78);
}
