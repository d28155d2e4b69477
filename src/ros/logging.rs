//! The node's log, as rcl's logging makes a stock node's: every record of the node's own
//! code at or above its logger's level goes to stderr and to `/rosout`.
//!
//! - **The level** (rcl's rules): `--log-level NAME:=LEVEL` for the node's logger
//!   (`cell1.tracer`: [`crate::names::NodeIdentity::logger_name`]) or an ancestor of it
//!   (`cell1`; the nearest wins), else `--log-level LEVEL`, else INFO. The node's own
//!   records (targets `tracer_calib*`) follow it; the libraries' (RustDDS, Zenoh) go to
//!   stderr alone, warnings and errors by default (`RUST_LOG` sets them), as a stock node's
//!   middleware logs never reach `/rosout`.
//! - **The sinks**: stderr unless `--disable-stdout-logs`; `/rosout` unless
//!   `--disable-rosout-logs`, once the node exists ([`attach_rosout`]): the record with its
//!   level, file, module (for the function, which Rust's records do not carry) and line,
//!   published by the node's loop (the middleware's `Wire::rosout`) under the rcl logger
//!   name. A record rate-limited at its call site is rate-limited on both.
//! - Records for `/rosout` wait in a queue of [`ROSOUT_QUEUE`]; when it is full (the node's
//!   loop stalled) they are dropped and counted ([`rosout_dropped`]), never blocking the
//!   code that logs.

use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock};

use log::{LevelFilter, Log, Metadata, Record};
use ros2_client::ros2::LogLevel as RosoutLevel;

use super::args::{LogLevel, RosArgs};

/// Records waiting for `/rosout` at most.
pub const ROSOUT_QUEUE: usize = 1000;

/// One record for `/rosout`.
#[derive(Debug, Clone, PartialEq)]
pub struct RosoutRecord {
    pub level: RosoutLevel,
    pub msg: String,
    pub file: String,
    /// The module path: Rust's log records carry no function name.
    pub function: String,
    pub line: u32,
}

impl RosoutRecord {
    fn of(record: &Record<'_>) -> RosoutRecord {
        RosoutRecord {
            level: match record.level() {
                log::Level::Error => RosoutLevel::Error,
                log::Level::Warn => RosoutLevel::Warn,
                log::Level::Info => RosoutLevel::Info,
                log::Level::Debug | log::Level::Trace => RosoutLevel::Debug,
            },
            msg: record.args().to_string(),
            file: record.file().unwrap_or_default().to_string(),
            function: record.module_path().unwrap_or_default().to_string(),
            line: record.line().unwrap_or(0),
        }
    }
}

/// The node's records: targets of this crate and of its binaries.
fn is_own(target: &str) -> bool {
    target.starts_with("tracer_calib")
}

struct NodeLogger {
    /// stderr, with the libraries' filter; the node's own records pass it (Trace), the
    /// node's level is applied here.
    stderr: env_logger::Logger,
    stdout_logs: bool,
    rosout_logs: bool,
    /// The node's level, a `LevelFilter` as usize.
    own_level: AtomicUsize,
    rosout: Mutex<Option<smol::channel::Sender<RosoutRecord>>>,
    dropped: AtomicU64,
}

impl NodeLogger {
    fn own_level(&self) -> LevelFilter {
        LEVELS[self.own_level.load(Ordering::Relaxed).min(LEVELS.len() - 1)]
    }
}

const LEVELS: [LevelFilter; 6] = [
    LevelFilter::Off,
    LevelFilter::Error,
    LevelFilter::Warn,
    LevelFilter::Info,
    LevelFilter::Debug,
    LevelFilter::Trace,
];

impl Log for NodeLogger {
    fn enabled(&self, metadata: &Metadata<'_>) -> bool {
        if is_own(metadata.target()) {
            metadata.level() <= self.own_level()
        } else {
            self.stdout_logs && self.stderr.enabled(metadata)
        }
    }

    fn log(&self, record: &Record<'_>) {
        if !is_own(record.target()) {
            if self.stdout_logs && self.stderr.matches(record) {
                self.stderr.log(record);
            }
            return;
        }
        if record.level() > self.own_level() {
            return;
        }
        if self.stdout_logs {
            self.stderr.log(record);
        }
        if let Some(tx) = self.rosout.lock().expect("rosout sender lock").as_ref()
            && tx.try_send(RosoutRecord::of(record)).is_err()
        {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }

    fn flush(&self) {
        self.stderr.flush();
    }
}

static LOGGER: OnceLock<&'static NodeLogger> = OnceLock::new();

/// The node logger's level by rcl's rules (module docs), for the logger `name`
/// (`None`: not known yet, the default level).
pub fn level_for(args: &RosArgs, name: Option<&str>) -> LevelFilter {
    let specific = name.and_then(|name| {
        args.logger_levels
            .iter()
            .filter(|(logger, _)| name == logger || name.starts_with(&format!("{logger}.")))
            .filter_map(|(logger, level)| level.level_filter().map(|f| (logger.len(), f)))
            // The nearest ancestor wins; of one logger, the last given.
            .fold(None, |best: Option<(usize, LevelFilter)>, (len, f)| match best {
                Some((b, _)) if b > len => best,
                _ => Some((len, f)),
            })
            .map(|(_, f)| f)
    });
    specific.or_else(|| args.log_level.and_then(LogLevel::level_filter)).unwrap_or(LevelFilter::Info)
}

/// Install the node's logger (once; later calls do nothing): stderr with the libraries'
/// filters, the node's own level from `args` (the default level until [`for_node`]).
pub fn install(args: &RosArgs) {
    if LOGGER.get().is_some() {
        return;
    }
    let mut builder = env_logger::Builder::new();
    // Microseconds, as a stock node's console lines have (rcutils: nanoseconds): a record
    // is set beside a peer's, or a network capture, by them.
    builder.format_timestamp_micros();
    builder.filter_level(LevelFilter::Warn);
    builder.filter_module("rustdds", LevelFilter::Error);
    // Its only error: leaving the discovery multicast group as the participant closes,
    // which fails (harmlessly) on loopback-only set-ups, two ERROR lines a shutdown.
    builder.filter_module("rustdds::network::udp_listener", LevelFilter::Off);
    // ros2-client's rosout_raw is a tracing span; with tracing's `log` feature on (zenoh
    // turns it on) every span would come out as an ERROR "rosout_raw;" line. Zenoh's own
    // tracing events still come through, as log records of their modules.
    builder.filter_module("tracing::span", LevelFilter::Off);
    // ros2-client echoes every record it publishes on /rosout as a tracing event: the
    // node has printed it already.
    builder.filter_module("ros2_client::rosout", LevelFilter::Off);
    // zenoh 1.8's admin space, as the session closes at shutdown, fails to publish the
    // closing links' events ("Unable to publish transport event: session closed", ERROR;
    // rmw_zenoh's processes print it too): harmless, and the admin space is all it logs.
    builder.filter_module("zenoh::api::admin", LevelFilter::Off);
    if let Ok(spec) = std::env::var("RUST_LOG") {
        builder.parse_filters(&spec);
    }
    // The node's own records pass; their level is the node logger's.
    builder.filter_module("tracer_calib", LevelFilter::Trace);
    builder.filter_module("tracer_calib_node", LevelFilter::Trace);
    let stderr = builder.build();
    let own = level_for(args, None);
    let logger: &'static NodeLogger = Box::leak(Box::new(NodeLogger {
        stdout_logs: args.stdout_logs.unwrap_or(true),
        rosout_logs: args.rosout_logs.unwrap_or(true),
        own_level: AtomicUsize::new(own as usize),
        rosout: Mutex::new(None),
        dropped: AtomicU64::new(0),
        stderr,
    }));
    if log::set_logger(logger).is_ok() {
        let _ = LOGGER.set(logger);
        set_max_level(logger);
    }
}

fn set_max_level(logger: &NodeLogger) {
    log::set_max_level(logger.own_level().max(logger.stderr.filter()));
}

/// The node's logger is `name` (`cell1.tracer`): its level by rcl's rules, which a
/// `--log-level NAME:=LEVEL` for it or an ancestor sets.
pub fn for_node(args: &RosArgs, name: &str) {
    if let Some(logger) = LOGGER.get() {
        logger.own_level.store(level_for(args, Some(name)) as usize, Ordering::Relaxed);
        set_max_level(logger);
    }
}

/// From now on the node's records also queue for `/rosout`: the receiver the node's loop
/// publishes from. `None` if the logger is not installed or `--disable-rosout-logs`.
pub fn attach_rosout() -> Option<smol::channel::Receiver<RosoutRecord>> {
    let logger = LOGGER.get().filter(|l| l.rosout_logs)?;
    let (tx, rx) = smol::channel::bounded(ROSOUT_QUEUE);
    *logger.rosout.lock().expect("rosout sender lock") = Some(tx);
    Some(rx)
}

/// No more records for `/rosout` (the node is closing).
pub fn detach_rosout() {
    if let Some(logger) = LOGGER.get() {
        *logger.rosout.lock().expect("rosout sender lock") = None;
    }
}

/// Records dropped because the `/rosout` queue was full.
pub fn rosout_dropped() -> u64 {
    LOGGER.get().map_or(0, |l| l.dropped.load(Ordering::Relaxed))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(list: &[&str]) -> RosArgs {
        let mut argv = vec!["node", "--ros-args"];
        argv.extend(list);
        RosArgs::parse(argv.iter().map(|s| s.to_string())).unwrap()
    }

    #[test]
    fn the_level_is_found_as_rcl_finds_it() {
        let none = args(&[]);
        assert_eq!(level_for(&none, Some("cell1.tracer")), LevelFilter::Info);
        let default = args(&["--log-level", "warn"]);
        assert_eq!(level_for(&default, Some("cell1.tracer")), LevelFilter::Warn);
        let mine = args(&["--log-level", "warn", "--log-level", "cell1.tracer:=debug"]);
        assert_eq!(level_for(&mine, Some("cell1.tracer")), LevelFilter::Debug);
        assert_eq!(level_for(&mine, Some("cell2.tracer")), LevelFilter::Warn);
        assert_eq!(level_for(&mine, None), LevelFilter::Warn);
        // An ancestor's level applies; the nearest wins; a name that only starts alike does not.
        let tree =
            args(&["--log-level", "cell1:=error", "--log-level", "cell1.tracer:=info", "--log-level", "cell:=debug"]);
        assert_eq!(level_for(&tree, Some("cell1.tracer")), LevelFilter::Info);
        assert_eq!(level_for(&tree, Some("cell1.other")), LevelFilter::Error);
        // `unset` leaves the next rule in force.
        let unset = args(&["--log-level", "error", "--log-level", "tracer:=unset"]);
        assert_eq!(level_for(&unset, Some("tracer")), LevelFilter::Error);
    }

    #[test]
    fn a_record_keeps_its_level_text_and_place() {
        let id = 7;
        let r = RosoutRecord::of(
            &Record::builder()
                .level(log::Level::Warn)
                .target("tracer_calib::cell")
                .args(format_args!("scan {id} refused"))
                .file(Some("src/cell/scans.rs"))
                .module_path(Some("tracer_calib::cell::scans"))
                .line(Some(42))
                .build(),
        );
        assert_eq!(
            r,
            RosoutRecord {
                level: RosoutLevel::Warn,
                msg: "scan 7 refused".into(),
                file: "src/cell/scans.rs".into(),
                function: "tracer_calib::cell::scans".into(),
                line: 42,
            }
        );
        assert!(is_own("tracer_calib_node") && is_own("tracer_calib::ros") && !is_own("rustdds::rtps"));
    }
}
