//! Real scene files' surface attributes through the real binary: vertex normals (`vn`)
//! shade by the interpolated normal, texture coordinates (`vt`) and `map_Kd` give the
//! albedo, and what cannot be loaded is said, not silently dropped.
mod common;

use common::{mean_and_block_rms, render_cpu, tmp_dir as dir};

use std::path::{Path, PathBuf};

use glam::Vec3;

/// Render `scene` on the CPU backend looking straight down at the floor quad, return the
/// image and stderr.
fn render(scene: &Path, out: &Path, extra: &[&str]) -> (runner::output::Image, String) {
    let mut args = vec![
        "--width",
        "64",
        "--height",
        "64",
        "--eye",
        "0,3,0",
        "--target",
        "0,0,0",
        "--up",
        "0,0,-1",
        "--fov",
        "30",
        "--max-depth",
        "2",
    ];
    args.extend_from_slice(extra);
    render_cpu(scene, out, &args)
}

fn mean(image: &runner::output::Image) -> f64 {
    image.pixels.iter().map(|p| p.x as f64).sum::<f64>() / image.pixels.len() as f64
}

/// A 2x2 floor at y = 0 (geometric normal +y) whose four corners all have the normal
/// `normal`, lit by a small emitter 50 units above it facing down.
fn tilted_floor(dir: &Path, normal: Vec3) -> PathBuf {
    let obj = format!(
        "mtllib s.mtl\n\
         v -1 0 -1\nv -1 0 1\nv 1 0 1\nv 1 0 -1\n\
         v -1 50 -1\nv 1 50 -1\nv 1 50 1\nv -1 50 1\n\
         vn {} {} {}\n\
         usemtl floor\nf 1//1 2//1 3//1 4//1\n\
         usemtl light\nf 5 6 7 8\n",
        normal.x, normal.y, normal.z
    );
    let mtl = "newmtl floor\nKd 0.5 0.5 0.5\nnewmtl light\nKd 0 0 0\nKe 625 625 625\n";
    std::fs::write(dir.join("s.mtl"), mtl).unwrap();
    let path = dir.join("floor.obj");
    std::fs::write(&path, obj).unwrap();
    path
}

#[test]
fn vertex_normals_shade_by_the_cosine_of_the_shading_normal() {
    // The light is straight above (to within 1/50): tilting every shading normal by θ scales
    // the direct light by cos θ, averaged over the symmetric view. Direct light of one small
    // light is nearly noise-free, so 2% is many standard errors.
    let d = dir("surfaces_normals");
    let theta = 40f32.to_radians();
    for integrator in ["nee", "mis", "ris", "restir"] {
        let flat = tilted_floor(&d, Vec3::Y);
        let (flat, _) = render(
            &flat,
            &d.join("flat.exr"),
            &["--integrator", integrator, "--spp", "16"],
        );
        let tilted = tilted_floor(&d, Vec3::new(0.0, theta.cos(), theta.sin()));
        let (tilted, _) = render(
            &tilted,
            &d.join("tilted.exr"),
            &["--integrator", integrator, "--spp", "16"],
        );
        let ratio = mean(&tilted) / mean(&flat);
        assert!(
            (ratio - theta.cos() as f64).abs() < 0.02,
            "{integrator}: tilted/flat = {ratio:.4}, expected cos 40° = {:.4}",
            theta.cos()
        );
        assert!(mean(&flat) > 0.05, "{integrator}: the floor is lit");
    }
}

#[test]
fn vertex_normals_on_the_far_side_are_turned_to_the_ray() {
    // Normals that point into the surface (inconsistent winding) shade like the side the
    // camera sees: here exactly the geometric normal, so the image is the flat one.
    let d = dir("surfaces_flipped");
    let (flat, _) = render(
        &tilted_floor(&d, Vec3::Y),
        &d.join("flat.exr"),
        &["--integrator", "nee", "--spp", "4"],
    );
    let (flipped, _) = render(
        &tilted_floor(&d, -Vec3::Y),
        &d.join("flipped.exr"),
        &["--integrator", "nee", "--spp", "4"],
    );
    assert_eq!(flat.pixels, flipped.pixels);
}

/// A 2x2 floor with texture coordinates u = (x + 1)/2, v = (1 - z)/2, so that seen from
/// above with -z at the top of the image it shows the texture upright.
fn textured_floor(dir: &Path, map: &str) -> PathBuf {
    let obj = "mtllib t.mtl\n\
               v -1 0 -1\nv -1 0 1\nv 1 0 1\nv 1 0 -1\n\
               vt 0 1\nvt 0 0\nvt 1 0\nvt 1 1\n\
               usemtl checker\nf 1/1 2/2 3/3 4/4\n";
    let mtl = format!("newmtl checker\nKd 0 0 0\nmap_Kd {map}\n");
    std::fs::write(dir.join("t.mtl"), mtl).unwrap();
    let path = dir.join("floor.obj");
    std::fs::write(&path, obj).unwrap();
    path
}

/// A 2×2 texture: top row red and green, bottom row blue and mid grey (sRGB 128).
fn save_checker(path: &Path) {
    let texels: [[u8; 4]; 4] = [
        [255, 0, 0, 255],
        [0, 255, 0, 255],
        [0, 0, 255, 255],
        [128, 128, 128, 255],
    ];
    let png = image::RgbaImage::from_raw(2, 2, texels.concat()).unwrap();
    png.save(path).unwrap();
}

/// `scene` (`textured_floor`) under a white sky and nothing else, where one bounce sees the
/// sky in every direction: each pixel's radiance is exactly the albedo, with no noise.
/// Every texture is found.
fn albedo_image(d: &Path, scene: &Path) -> runner::output::Image {
    let (image, stderr) = render(
        scene,
        &d.join("t.exr"),
        &["--integrator", "nee", "--sky", "1,1,1", "--spp", "4"],
    );
    assert!(!stderr.contains("warning: texture"), "{stderr}");
    image
}

#[test]
fn map_kd_gives_the_albedo_at_the_texture_coordinates() {
    let d = dir("surfaces_texture");
    std::fs::create_dir_all(d.join("tex")).unwrap();
    save_checker(&d.join("tex/checker.png"));
    // Options before the name and a Windows path, as exporters write them.
    let scene = textured_floor(&d, "-bm 1 tex\\checker.png");
    let image = albedo_image(&d, &scene);
    let grey = kernels::texture::srgb_to_linear(128.0 / 255.0);
    // Pixels over the texel centres (uv 0.25 / 0.75): 0.5 ± 0.5/tan(15°)/3 of the width.
    let at = |fx: f32, fy: f32| image.pixels[((fy * 64.0) as usize) * 64 + (fx * 64.0) as usize];
    let (lo, hi) = (0.5 - 0.311, 0.5 + 0.311);
    for (pixel, expected, what) in [
        (at(lo, lo), Vec3::new(1.0, 0.0, 0.0), "top left: red"),
        (at(hi, lo), Vec3::new(0.0, 1.0, 0.0), "top right: green"),
        (at(lo, hi), Vec3::new(0.0, 0.0, 1.0), "bottom left: blue"),
        (
            at(hi, hi),
            Vec3::splat(grey),
            "bottom right: sRGB 128 decoded",
        ),
    ] {
        // Bilinear filtering blends in a little of the neighbours within a pixel.
        assert!(
            (pixel - expected).abs().max_element() < 0.05,
            "{what}: {pixel} vs {expected}"
        );
    }
}

/// A map statement's options: `-s` and `-o` place the texture (uv read at s·uv + o),
/// `-clamp on` keeps its edge texels beyond [0, 1]; and a file name with a space (Blender
/// writes names as they are) is found. Before, the name's last word was taken as the file,
/// and the options were read for `-bm` alone.
#[test]
fn map_options_scale_offset_and_clamp_the_texture() {
    let d = dir("surfaces_map_options");
    save_checker(&d.join("check er.png"));
    // The view spans uv 0.1..0.9; scaled by ¼ and moved right by ¾ that is u' 0.775..0.975,
    // v' 0.025..0.225: from the bottom right (grey) texel's centre outwards, where a
    // repeating texture would blend in its opposite edges (up to 45%).
    let scene = textured_floor(&d, "-s 0.25 0.25 -o 0.75 0 -clamp on check er.png");
    let image = albedo_image(&d, &scene);
    let grey = kernels::texture::srgb_to_linear(128.0 / 255.0);
    let worst = image
        .pixels
        .iter()
        .map(|p| (*p - Vec3::splat(grey)).abs().max_element())
        .fold(0.0, f32::max);
    assert!(worst < 1e-3, "a pixel {worst} off the grey texel");
}

/// A texture finer than the pixels that see it (256² one-texel checks of black and white
/// on a floor 64 pixels wide: about 3 texels a pixel) is read from its mip levels, where
/// each pixel finds the checks' average (half the light) in one sample; read at a point,
/// each sample was black or white (0.5 off).
#[test]
fn a_texture_finer_than_the_pixels_reads_its_average_in_one_sample() {
    let d = dir("surfaces_minified");
    let checks = image::RgbaImage::from_fn(256, 256, |x, y| {
        let c = if (x + y) % 2 == 0 { 255 } else { 0 };
        image::Rgba([c, c, c, 255])
    });
    checks.save(d.join("checks.png")).unwrap();
    let scene = textured_floor(&d, "checks.png");
    let (image, stderr) = render(
        &scene,
        &d.join("t.exr"),
        &["--integrator", "nee", "--sky", "1,1,1", "--spp", "1"],
    );
    assert!(!stderr.contains("warning: texture"), "{stderr}");
    // sRGB 188, the encoded average of the level below, is 0.503 linear: within 0.01 of
    // half; a point sample is 0.5 off, so that a few of them would fail the mean.
    let off: Vec<f32> = image.pixels.iter().map(|p| (p.x - 0.5).abs()).collect();
    let mean_off = off.iter().sum::<f32>() / off.len() as f32;
    let worst = off.iter().fold(0f32, |a, &b| a.max(b));
    assert!(
        mean_off < 0.01 && worst < 0.05,
        "mean {mean_off}, worst {worst}"
    );
}

#[test]
fn a_missing_texture_is_a_warning_and_kd_stays() {
    let d = dir("surfaces_missing_texture");
    let scene = textured_floor(&d, "nowhere.png");
    let (image, stderr) = render(
        &scene,
        &d.join("t.exr"),
        &["--integrator", "nee", "--sky", "1,1,1", "--spp", "1"],
    );
    assert!(
        stderr.contains("warning: texture 'nowhere.png' (map_Kd of material 'checker') not loaded")
            && stderr.contains("tried"),
        "{stderr}"
    );
    // Kd 0: black, as the file says when its texture is gone.
    assert_eq!(mean(&image), 0.0);
}

/// The Cornell box's walls and light (its two blocks left out) with two smooth spheres of
/// radius 100 (icosphere, 1280 faces, vertex normals) of materials `left` and `right`,
/// defined in `mtl` besides the box's own.
fn cornell_spheres(dir: &Path, name: &str, left: &str, right: &str, mtl: &str) -> PathBuf {
    let mut obj = String::new();
    let mut skip = false;
    for line in runner::scene::CORNELL_BOX_OBJ.lines() {
        if let Some(object) = line.strip_prefix("o ") {
            skip = object.ends_with("_block");
        }
        if line.starts_with("mtllib") {
            obj += &format!("mtllib {name}.mtl\n");
        } else if !skip {
            obj += line;
            obj.push('\n');
        }
    }
    let mut vertices = obj.lines().filter(|l| l.starts_with("v ")).count();
    let mut normals = 0;
    let (unit, faces) = runner::generate::icosphere_mesh(3);
    for (centre, material) in [
        (Vec3::new(186.0, 100.0, 370.0), left),
        (Vec3::new(380.0, 100.0, 190.0), right),
    ] {
        obj += &format!("o {material}_sphere\nusemtl {material}\n");
        for p in &unit {
            let q = centre + *p * 100.0;
            obj += &format!("v {} {} {}\n", q.x, q.y, q.z);
        }
        for p in &unit {
            obj += &format!("vn {} {} {}\n", p.x, p.y, p.z);
        }
        for f in &faces {
            let (a, b, c) = (f[0] + 1, f[1] + 1, f[2] + 1);
            obj += &format!(
                "f {}//{} {}//{} {}//{}\n",
                a + vertices,
                a + normals,
                b + vertices,
                b + normals,
                c + vertices,
                c + normals
            );
        }
        vertices += unit.len();
        normals += unit.len();
    }
    let box_mtl = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/cornell_box.mtl"),
    )
    .unwrap();
    std::fs::write(dir.join(format!("{name}.mtl")), box_mtl + mtl).unwrap();
    let path = dir.join(format!("{name}.obj"));
    std::fs::write(&path, obj).unwrap();
    path
}

/// The scenes compared with Mitsuba 3, written to $CARGO_TARGET_TMPDIR/surfaces_mitsuba;
/// tests/references/mitsuba_surfaces.py renders its references from those files.
fn mitsuba_scenes(dir: &Path) -> Vec<(&'static str, PathBuf)> {
    vec![
        (
            "mirror_glass",
            cornell_spheres(
                dir,
                "mirror_glass",
                "mirror",
                "glass",
                "\nnewmtl mirror\nKd 0 0 0\nKs 1 1 1\nillum 3\nnewmtl glass\nKd 0 0 0\nNi 1.5\nillum 7\n",
            ),
        ),
        (
            "rough",
            cornell_spheres(
                dir,
                "rough",
                "metal",
                "frosted",
                "\nnewmtl metal\nKd 0 0 0\nKs 1 1 1\nNs 30\nillum 2\nnewmtl frosted\nKd 0 0 0\nNi 1.5\nPr 0.5\nillum 7\n",
            ),
        ),
    ]
}

#[test]
fn glass_mirror_and_rough_surfaces_agree_with_mitsuba() {
    let d = dir("surfaces_mitsuba");
    let references = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/references");
    // MIS with many samples: tight; the other estimators (the BSDF inside RIS's and ReSTIR's
    // target, delta surfaces continued by a path) with fewer, so looser block errors.
    // ReSTIR runs its default, unbiased weighting (measured: within 0.1% of the mean).
    let runs = [
        ("mis", "1024", 0.05),
        ("nee", "256", 0.08),
        ("ris", "256", 0.08),
        ("restir", "256", 0.08),
    ];
    for (name, scene) in mitsuba_scenes(&d) {
        let reference =
            runner::output::read_image(&references.join(format!("surfaces_{name}_96.exr")))
                .unwrap();
        for (integrator, spp, max_rms) in runs {
            let out = d.join(format!("{name}_{integrator}.exr"));
            let (image, _) = render_cpu(
                &scene,
                &out,
                &[
                    "--width",
                    "96",
                    "--height",
                    "96",
                    "--spp",
                    spp,
                    "--integrator",
                    integrator,
                ],
            );
            let (rel, rms) = mean_and_block_rms(&image, &reference, 12);
            eprintln!(
                "{name} {integrator}: mean {rel:+.4} relative, block RMS {rms:.4} of the mean"
            );
            assert!(
                rel.abs() < 0.02,
                "{name} {integrator}: mean {rel:+.4} of Mitsuba's"
            );
            assert!(rms < max_rms, "{name} {integrator}: block RMS {rms:.4}");
        }
    }
}

/// Radiance of the grey floor (albedo ½) of `sheet_over_floor` in the open, under its sun
/// (radiance 100 over a disk of radius r = 1°): ρ/π · L_sun · 2π(1 − cos r).
fn sunlit_floor() -> f32 {
    let radius = 1f32.to_radians();
    0.5 / std::f32::consts::PI * 100.0 * 2.0 * std::f32::consts::PI * (1.0 - radius.cos())
}

/// A black sheet (MTL `sheet_lines` after `Kd 0 0 0`) at height 1 over a 10 × 10 grey floor,
/// with texture coordinates on the sheet when `uvs`, seen from the default camera by `nee`
/// at `spp` under a sun straight above (see `sunlit_floor`).
fn sheet_over_floor(
    d: &Path,
    sheet_lines: &str,
    uvs: bool,
    spp: &str,
) -> (runner::output::Image, String) {
    let mtl = format!("newmtl floor\nKd 0.5 0.5 0.5\nnewmtl sheet\nKd 0 0 0\n{sheet_lines}\n");
    std::fs::write(d.join("sheet.mtl"), mtl).unwrap();
    let (texcoords, sheet_face) = if uvs {
        ("vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n", "f 5/1 8/4 7/3 6/2")
    } else {
        ("", "f 5 8 7 6")
    };
    let obj = format!(
        "mtllib sheet.mtl\n\
         v -5 0 -5\nv 5 0 -5\nv 5 0 5\nv -5 0 5\n\
         v -1 1 -1\nv 1 1 -1\nv 1 1 1\nv -1 1 1\n\
         {texcoords}usemtl floor\nf 1 4 3 2\nusemtl sheet\n{sheet_face}\n"
    );
    let scene = d.join("sheet.obj");
    std::fs::write(&scene, obj).unwrap();
    let args = [
        "--integrator",
        "nee",
        "--spp",
        spp,
        "--sun",
        "0,1,0",
        "--sun-radiance",
        "100,100,100",
        "--sun-angle",
        "2",
    ];
    render(&scene, &d.join("sheet.exr"), &args)
}

/// Mean red radiance of rows 24..40 and columns `columns` of a 64 × 64 image.
fn middle_rows_mean(image: &runner::output::Image, columns: std::ops::Range<usize>) -> f32 {
    let mut s = 0.0;
    for y in 24..40 {
        for x in columns.clone() {
            s += image.pixels[y * 64 + x].x;
        }
    }
    s / (16 * columns.len()) as f32
}

#[test]
fn cutout_masks_are_holes_for_camera_and_shadow_rays() {
    // A black plane at height 1 over a grey floor (albedo 0.5), under a sun straight above.
    // The plane's `map_d` is a 2×1 mask: transparent on the side of u < ½, opaque on the
    // other. Through the hole the camera sees the floor, lit by the sun through the same
    // hole: `sunlit_floor`. Were camera rays blocked there, the black plane would show;
    // were shadow rays, the floor would be dark. The other side shows the plane (black).
    // Both mask kinds: a grey-level image and an image with an alpha channel.
    let d = dir("surfaces_cutout");
    let grey = image::GrayImage::from_raw(2, 1, vec![0, 255]).unwrap();
    grey.save(d.join("mask_grey.png")).unwrap();
    let rgba =
        image::RgbaImage::from_raw(2, 1, vec![255, 255, 255, 0, 255, 255, 255, 255]).unwrap();
    rgba.save(d.join("mask_alpha.png")).unwrap();
    let expected = sunlit_floor();
    for mask in ["mask_grey.png", "mask_alpha.png"] {
        let (image, stderr) = sheet_over_floor(&d, &format!("map_d {mask}"), true, "16");
        assert!(!stderr.contains("map_d"), "map_d is read: {stderr}");
        // The middle rows in the left and right quarters of the image.
        let (a, b) = (
            middle_rows_mean(&image, 2..14),
            middle_rows_mean(&image, 50..62),
        );
        let (hole, solid) = if a > b { (a, b) } else { (b, a) };
        assert!(
            (hole / expected - 1.0).abs() < 0.02 && solid < 0.01 * expected,
            "{mask}: through the hole {hole} (expected {expected}), on the sheet {solid}"
        );
    }
}

#[test]
fn dissolve_is_the_share_of_the_surface_that_is_there() {
    // The black sheet of `cutout_masks_are_holes_for_camera_and_shadow_rays`, now `d 0.25`
    // (no map, and no texture coordinates on its face): a quarter of it is there, so ¾ of
    // the sunlight reaches the floor below and ¾ of the camera's rays see it: (¾)² of the
    // open floor's radiance, everywhere under the sheet. Glass (`illum 7`) ignores `d`.
    let d = dir("surfaces_dissolve");
    let (image, stderr) = sheet_over_floor(&d, "d 0.25", false, "64");
    assert!(!stderr.contains("d < 1"), "d is read: {stderr}");
    let under = middle_rows_mean(&image, 16..48) / sunlit_floor();
    assert!((under - 0.5625).abs() < 0.03, "{under} vs 0.5625");
}
