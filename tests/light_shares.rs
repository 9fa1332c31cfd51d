//! How NEE splits its samples between emissive triangles, the environment map and the sun
//! (`--light-shares`): `seen` measures each kind's light where the camera looks.
mod common;

use clap::Parser;
use common::tmp_dir;
use runner::cli::{Cli, Command};
use runner::options::frame_params;

/// A 4 x 4 x 4 room (walls facing in; `ceiling` or open to the sky above) with a 1 x 1
/// emitter just under its top, as OBJ + MTL.
fn write_room(path: &std::path::Path, ceiling: bool) {
    let mut obj = String::from("mtllib room.mtl\n");
    obj += "v -2 -2 -2\nv 2 -2 -2\nv 2 2 -2\nv -2 2 -2\nv -2 -2 2\nv 2 -2 2\nv 2 2 2\nv -2 2 2\n";
    obj += "v -0.5 1.9 -0.5\nv 0.5 1.9 -0.5\nv 0.5 1.9 0.5\nv -0.5 1.9 0.5\n";
    obj += "usemtl wall\nf 1 2 3 4\nf 5 8 7 6\nf 1 5 6 2\nf 1 4 8 5\nf 2 6 7 3\n";
    if ceiling {
        obj += "f 4 3 7 8\n";
    }
    obj += "usemtl lamp\nf 9 10 11 12\n";
    std::fs::write(path, obj).unwrap();
    std::fs::write(
        path.with_file_name("room.mtl"),
        "newmtl wall\nKd 0.5 0.5 0.5\nnewmtl lamp\nKd 0 0 0\nKe 10 10 10\n",
    )
    .unwrap();
}

/// A constant equirectangular map of radiance 1.
fn write_sky(path: &std::path::Path) {
    let texels = vec![image::Rgb([1.0f32; 3]); 16 * 8];
    let file = std::fs::File::create(path).unwrap();
    image::codecs::hdr::HdrEncoder::new(file)
        .encode(&texels, 16, 8)
        .unwrap();
}

/// The map's share of NEE's samples under `rule`, camera inside the room looking at a wall.
fn map_share(ceiling: bool, rule: &str) -> f32 {
    let d = tmp_dir(&format!("light_shares_{ceiling}_{rule}"));
    let (room, sky) = (d.join("room.obj"), d.join("sky.hdr"));
    write_room(&room, ceiling);
    write_sky(&sky);
    let cli = Cli::try_parse_from([
        "runner",
        "bench",
        "--scene",
        room.to_str().unwrap(),
        "--env",
        sky.to_str().unwrap(),
        "--eye",
        "0,-1,1.5",
        "--target",
        "0,-1,-2",
        "--light-shares",
        rule,
    ])
    .unwrap();
    let Command::Bench(args) = cli.command else {
        unreachable!()
    };
    let mut scene = runner::scene::load(&args.scene).unwrap();
    let params = frame_params(&args.scene, &args.kernel, &mut scene).unwrap();
    assert_eq!(params.sun_light_probability, 0.0, "no sun");
    params.env_light_probability
}

#[test]
fn a_closed_room_gives_the_map_outside_only_the_defensive_share() {
    // Power counts the map's light over the scene's bounding disk: most of it, though
    // none gets in. The pilot sees none, and leaves the map its defensive minimum (20% of
    // the samples are split equally between the two kinds).
    let power = map_share(true, "power");
    let seen = map_share(true, "seen");
    assert!(power > 0.5, "power: {power}");
    assert!((seen - 0.1).abs() < 1e-6, "seen: {seen}");
    assert_eq!(map_share(true, "equal"), 0.5);
}

#[test]
fn an_open_room_gives_the_map_most_samples() {
    // Without a ceiling the sky lights the whole room, a 1 x 1 lamp little of it.
    let seen = map_share(false, "seen");
    assert!(seen > 0.5, "seen: {seen}");
}
