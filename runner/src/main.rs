use std::process::ExitCode;

use clap::Parser;
use runner::cli::{Cli, Command};
use runner::error::Result;

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
    // The CWBVH's leaves priced for where the kernels will run (`collapse`).
    let device = match &cli.command {
        Command::Render(args) => Some(&args.device),
        Command::Bench(args) => Some(&args.device),
        Command::View(args) => Some(&args.device),
        _ => None,
    };
    runner::collapse::set_for_cpu(device.is_some_and(|d| runner::backend::expects_cpu(d.backend)));
    let result = match cli.command {
        Command::Render(args) => runner::render::run(&args),
        Command::Bench(args) if args.suite => {
            runner::bench::suite(&args).and_then(|table| print_stdout(&table))
        }
        Command::Bench(args) => runner::bench::bench(&args)
            .and_then(|r| print_stdout(&if args.json { r.json() } else { r.table() })),
        Command::Generate(args) => runner::generate::run(&args),
        Command::Compare(args) => {
            runner::output::compare_report(&args).and_then(|r| print_stdout(&r))
        }
        Command::View(args) => runner::viewer::app::check_args(&args)
            .and_then(|()| runner::scene::load(&args.scene))
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
