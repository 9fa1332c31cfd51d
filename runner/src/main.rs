use std::process::ExitCode;

use clap::Parser;
use runner::cli::{Cli, Command, CompareArgs, GenerateArgs, RenderArgs};
use runner::error::{Context, Result};
use runner::output::{check_writable, write_image};
use runner::render::open_backend;
use runner::setup::{frame_params, load_scene, orbit_camera};

fn main() -> ExitCode {
    // `view --present auto` asks a child process whether the GPU can present to the display.
    if std::env::var_os(runner::viewer::present::PROBE_ENV).is_some() {
        return runner::viewer::present::probe_child();
    }
    // Past a file-size limit (`ulimit -f`) the kernel would kill us mid-write with SIGXFSZ;
    // ignored, the write fails with EFBIG, which `output::write_file` reports (the old output
    // stays, as the new one goes to a temporary file first).
    // SAFETY: setting a signal's disposition to SIG_IGN has no preconditions.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
    // Bad input is reported as errors everywhere we know of; should anything still panic
    // (a dependency, say), say so on one line rather than with a backtrace.
    if std::env::var_os("RUST_BACKTRACE").is_none() {
        std::panic::set_hook(Box::new(|info| {
            let msg = info
                .payload()
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| info.payload().downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            let at = info
                .location()
                .map(|l| format!(" at {}:{}", l.file(), l.line()))
                .unwrap_or_default();
            eprintln!(
                "error: internal error: {msg}{at} (please report it; RUST_BACKTRACE=1 for details)"
            );
        }));
    }
    let cli = Cli::parse();
    if let Err(e) = runner::logging::init_from_env() {
        eprintln!("error: {e}");
        return ExitCode::FAILURE;
    }
    let result = match cli.command {
        Command::Render(args) => render_command(&args),
        Command::Bench(args) => runner::bench::bench(&args)
            .and_then(|r| print_stdout(&if args.json { r.json() } else { r.table() })),
        Command::Generate(args) => generate_command(&args),
        Command::Compare(args) => compare_command(&args),
        Command::View(args) => runner::viewer::app::check_args(&args)
            .and_then(|()| load_scene(&args.scene))
            .and_then(|scene| runner::viewer::app::run(&args, scene)),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn render_command(args: &RenderArgs) -> Result<()> {
    let started = std::time::Instant::now();
    let format = check_writable(&args.out)?;
    if args.frames == 0 {
        runner::bail!("--frames must be at least 1");
    }
    if !args.orbit.is_finite() {
        runner::bail!("--orbit must be a finite number of degrees");
    }
    if let Some(scene_file) = args.scene.scene.as_ref().filter(|p| p.is_file()) {
        if std::fs::canonicalize(scene_file).ok() == std::fs::canonicalize(&args.out).ok() {
            runner::bail!(
                "--out '{}' is the scene file itself; it would be overwritten",
                args.out.display()
            );
        }
    }
    if let Some(dir) = args.out_dir.as_ref().filter(|d| d.exists() && !d.is_dir()) {
        runner::bail!(
            "--out-dir '{}' exists and is not a directory",
            dir.display()
        );
    }
    let scene = load_scene(&args.scene)?;
    let mut params = frame_params(&args.scene, &args.kernel, &scene)?;
    // Frame F of a sequence draws the random numbers of samples F·spp onwards.
    let samples_end = (args.first_frame as u64 + args.frames as u64) * args.kernel.spp as u64;
    if samples_end > u32::MAX as u64 {
        runner::bail!("--first-frame, --frames and --spp together exceed 2^32 samples");
    }
    params.frame = args.first_frame * args.kernel.spp;
    params.sample_offset = args.first_frame * args.kernel.spp;
    // Created only once the scene has loaded: a run that fails on its input leaves nothing.
    if let Some(dir) = &args.out_dir {
        std::fs::create_dir_all(dir)
            .context(|| format!("cannot create --out-dir '{}'", dir.display()))?;
    }
    let mut backend = open_backend(args.kernel.backend, &scene, params.width, params.height)?;
    let k = &args.kernel;
    eprintln!(
        "{} triangles ({} emissive), {}x{}, {} spp x {} frame(s), integrator {}{}, BVH {}, backend {}",
        scene.triangles.len(),
        scene.lights.len(),
        params.width,
        params.height,
        k.spp,
        args.frames,
        k.integrator.name(),
        if k.integrator == runner::cli::Integrator::Restir {
            if params.restir_flags & kernels::types::RESTIR_UNBIASED != 0 {
                " (unbiased)"
            } else {
                " (biased)"
            }
        } else {
            ""
        },
        kernels::bvh::TRAVERSAL,
        backend.describe()
    );
    let ext = match format {
        runner::output::OutputFormat::Png => "png",
        runner::output::OutputFormat::Exr => "exr",
    };
    let (image, stats) = runner::render::render_sequence(
        backend.as_mut(),
        k.integrator,
        &params,
        k.spp,
        args.frames,
        args.accumulate,
        |f| {
            orbit_camera(
                &args.scene,
                &scene,
                args.orbit * (args.first_frame as u64 + f as u64) as f32,
            )
        },
        |f, image| match &args.out_dir {
            Some(dir) => write_image(&dir.join(format!("frame_{f:04}.{ext}")), image),
            None => Ok(()),
        },
    )?;
    write_image(&args.out, &image)?;
    let kernel_s = stats.pass_ms.iter().sum::<f64>() * 1e-3;
    eprintln!(
        "wrote {} in {:.2} s: {}x{}, {} spp x {} frame(s), {} rays ({} rays/s over {kernel_s:.2} s of kernel time)",
        args.out.display(),
        started.elapsed().as_secs_f64(),
        params.width,
        params.height,
        k.spp,
        args.frames,
        runner::bench::with_unit(stats.rays as f64),
        runner::bench::with_unit(stats.rays as f64 / kernel_s.max(1e-9)),
    );
    Ok(())
}

fn generate_command(args: &GenerateArgs) -> Result<()> {
    if args
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mtl"))
    {
        runner::bail!(
            "--out '{}' names the MTL file; give the OBJ file (the MTL is written beside it)",
            args.out.display()
        );
    }
    let generated = match runner::generate::builtin(&args.name) {
        Some(g) => g?,
        None => runner::bail!(
            "no built-in scene '{}' ({})",
            args.name,
            runner::generate::BUILTIN_NAMES
        ),
    };
    let mtl_path = args.out.with_extension("mtl");
    let mtl_name = mtl_path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let (obj, mtl) = runner::generate::to_obj(&generated, &mtl_name);
    runner::output::write_file(&args.out, obj.as_bytes())?;
    runner::output::write_file(&mtl_path, mtl.as_bytes())?;
    eprintln!(
        "wrote {} and {} ({} triangles)",
        args.out.display(),
        mtl_path.display(),
        generated.triangles.len()
    );
    Ok(())
}

fn compare_command(args: &CompareArgs) -> Result<()> {
    let image = runner::output::read_image(&args.image)?;
    let reference = runner::output::read_image(&args.reference)?;
    let e = runner::output::compare(&image, &reference)?;
    print_stdout(&format!(
        "rmse {:.6}  relmse {:.6}  max_abs {:.6}  identical {:.2}%  (mean {:.5} vs {:.5})",
        e.rmse,
        e.rel_mse,
        e.max_abs,
        100.0 * e.identical,
        image.mean().dot(glam::Vec3::splat(1.0 / 3.0)),
        reference.mean().dot(glam::Vec3::splat(1.0 / 3.0)),
    ))
}

/// Exit status of a program whose reader went away, as Unix tools report it (128 + SIGPIPE).
const EXIT_BROKEN_PIPE: i32 = 141;

/// Print a line of results; a reader that has gone away (`runner compare ... | head -0`)
/// ends the program quietly, as it would any Unix tool, instead of a panic in `println!`.
fn print_stdout(text: &str) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match writeln!(out, "{text}").and_then(|()| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {
            std::process::exit(EXIT_BROKEN_PIPE)
        }
        Err(e) => Err(runner::error::Error(format!(
            "cannot write to standard output: {e}"
        ))),
    }
}
