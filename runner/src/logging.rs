//! `RUNNER_LOG=<level>` (error, warn, info, debug, trace) prints the log records of the
//! runner and its dependencies (wgpu's Vulkan backend, winit) to stderr: the first thing to
//! look at when a driver misbehaves. Unset, nothing is logged.
use log::{Level, LevelFilter, Log, Metadata, Record};

struct Stderr(LevelFilter);

impl Log for Stderr {
    fn enabled(&self, metadata: &Metadata) -> bool {
        metadata.level() <= self.0
    }

    fn log(&self, record: &Record) {
        if self.enabled(record.metadata()) {
            eprintln!("[{} {}] {}", record.level(), record.target(), record.args());
        }
    }

    fn flush(&self) {}
}

/// Install the logger if `RUNNER_LOG` names a level; an unknown level is an error.
pub fn init_from_env() -> crate::error::Result<()> {
    let Some(value) = std::env::var_os("RUNNER_LOG") else {
        return Ok(());
    };
    let value = value.to_string_lossy();
    let level: LevelFilter = match value.parse::<Level>() {
        Ok(level) => level.to_level_filter(),
        Err(_) => crate::bail!(
            "RUNNER_LOG='{value}' is not a log level (error, warn, info, debug, trace)"
        ),
    };
    let logger: &'static Stderr = Box::leak(Box::new(Stderr(level)));
    log::set_logger(logger)
        .map_err(|e| crate::error::Error(format!("cannot install the logger: {e}")))?;
    log::set_max_level(level);
    Ok(())
}
