//! The tracer driver's health, as `/diagnostics` reports it: whether anything publishes the
//! raw scans, how long since the last one came, and at what rate they come.
//!
//! A status of its own beside the calibration's, laid out as `diagnostic_updater` lays out
//! a task's: named `tracer_calib: /ns/node: tracer driver` (so that a
//! `diagnostic_aggregator` analyzer that matches the node's name takes both), the node's
//! `hardware_id`, a level and a message, then key/values. WARN when no driver publishes
//! `raw_scan`, or when no scan came for longer than `driver.scan_timeout` (0: never; a
//! tracer idles between jobs); OK otherwise.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use crate::interfaces::{DiagnosticStatus, KeyValue};

/// The window the scan rate is measured over.
pub const RATE_WINDOW: Duration = Duration::from_secs(10);

/// What the node knows of the driver.
#[derive(Debug, Clone)]
pub struct DriverWatch {
    /// The raw scan topic, as resolved (for the messages).
    pub topic: String,
    /// When the watch began (the node's start).
    since: Instant,
    /// When the last raw scan (good or not) came.
    last_scan: Option<Instant>,
    /// Publishers matched on the raw scan topic at the last tick; `None` before the first.
    publishers: Option<usize>,
    /// `(when, scans received by then)` at the ticks of the last [`RATE_WINDOW`].
    counts: VecDeque<(Instant, u64)>,
}

impl DriverWatch {
    /// Watching from `now`.
    pub fn new(now: Instant) -> Self {
        DriverWatch { topic: "raw_scan".into(), since: now, last_scan: None, publishers: None, counts: VecDeque::new() }
    }

    /// A raw scan came at `now`.
    pub fn scan_arrived(&mut self, now: Instant) {
        self.last_scan = Some(now);
    }

    /// Once a second: the publishers matched on the topic, and the scans received so far.
    pub fn tick(&mut self, now: Instant, publishers: usize, scans_received: u64) {
        self.publishers = Some(publishers);
        self.counts.push_back((now, scans_received));
        while self.counts.front().is_some_and(|(t, _)| now.duration_since(*t) > RATE_WINDOW) {
            self.counts.pop_front();
        }
    }

    /// Scans a second over the window's ticks; 0 before two ticks.
    pub fn rate(&self) -> f64 {
        match (self.counts.front(), self.counts.back()) {
            (Some((t0, n0)), Some((t1, n1))) if t1 > t0 => (n1 - n0) as f64 / t1.duration_since(*t0).as_secs_f64(),
            _ => 0.0,
        }
    }

    /// The status at `now` (module docs), for the node `fqn` with `hardware_id`,
    /// `scan_timeout` seconds (0: none) and `scans_received` so far.
    pub fn status(
        &self,
        now: Instant,
        fqn: &str,
        hardware_id: &str,
        scan_timeout: f64,
        scans_received: u64,
    ) -> DiagnosticStatus {
        let quiet = now.duration_since(self.last_scan.unwrap_or(self.since)).as_secs_f64();
        let (level, message) = match (self.publishers, self.last_scan) {
            (Some(0), _) => (DiagnosticStatus::WARN, format!("no tracer driver: nothing publishes {}", self.topic)),
            _ if scan_timeout > 0.0 && quiet > scan_timeout => (
                DiagnosticStatus::WARN,
                match self.last_scan {
                    Some(_) => {
                        format!("scans stopped: none for {quiet:.0} s (driver.scan_timeout is {scan_timeout} s)")
                    }
                    None => format!("no scan yet, {quiet:.0} s after start (driver.scan_timeout is {scan_timeout} s)"),
                },
            ),
            (publishers, Some(_)) => (
                DiagnosticStatus::OK,
                format!("{} publisher(s) on {}; last scan {quiet:.1} s ago", publishers.unwrap_or(0), self.topic),
            ),
            (publishers, None) => (
                DiagnosticStatus::OK,
                format!("{} publisher(s) on {}; no scan yet", publishers.unwrap_or(0), self.topic),
            ),
        };
        let kv = |k: &str, v: String| KeyValue { key: k.to_string(), value: v };
        DiagnosticStatus {
            level,
            name: format!("tracer_calib: {fqn}: tracer driver"),
            message,
            hardware_id: hardware_id.to_string(),
            values: vec![
                kv("topic", self.topic.clone()),
                kv("publishers", self.publishers.map(|n| n.to_string()).unwrap_or_default()),
                kv("scans_received", scans_received.to_string()),
                kv(
                    "seconds_since_last_scan",
                    self.last_scan.map(|t| format!("{:.1}", now.duration_since(t).as_secs_f64())).unwrap_or_default(),
                ),
                kv("scan_rate_hz", format!("{:.2}", self.rate())),
                kv("rate_window_s", RATE_WINDOW.as_secs().to_string()),
                kv("scan_timeout_s", scan_timeout.to_string()),
            ],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn value<'a>(s: &'a DiagnosticStatus, key: &str) -> &'a str {
        &s.values.iter().find(|v| v.key == key).unwrap().value
    }

    #[test]
    fn missing_present_and_stopped() {
        let t0 = Instant::now();
        let at = |s: f64| t0 + Duration::from_secs_f64(s);
        let mut w = DriverWatch::new(t0);
        w.topic = "/cell1/raw_scan".into();
        // Nothing publishes.
        w.tick(at(1.0), 0, 0);
        let s = w.status(at(1.0), "/cell1/tracer", "SN-7", 5.0, 0);
        assert_eq!(s.level, DiagnosticStatus::WARN);
        assert_eq!(s.message, "no tracer driver: nothing publishes /cell1/raw_scan");
        assert_eq!((s.name.as_str(), s.hardware_id.as_str()), ("tracer_calib: /cell1/tracer: tracer driver", "SN-7"));
        assert_eq!(value(&s, "publishers"), "0");
        // A driver, scanning at 2 Hz for 10 s.
        for i in 0..=20 {
            w.scan_arrived(at(2.0 + 0.5 * f64::from(i)));
            if i % 2 == 0 {
                w.tick(at(2.0 + 0.5 * f64::from(i)), 1, u64::from(i as u16 + 1));
            }
        }
        let s = w.status(at(12.2), "/cell1/tracer", "SN-7", 5.0, 21);
        assert_eq!(s.level, DiagnosticStatus::OK, "{}", s.message);
        assert_eq!(s.message, "1 publisher(s) on /cell1/raw_scan; last scan 0.2 s ago");
        assert_eq!(value(&s, "scan_rate_hz"), "2.00");
        assert_eq!(value(&s, "seconds_since_last_scan"), "0.2");
        // It stops: after the timeout, WARN; with no timeout, still OK.
        let s = w.status(at(18.0), "/cell1/tracer", "SN-7", 5.0, 21);
        assert_eq!(s.level, DiagnosticStatus::WARN);
        assert_eq!(s.message, "scans stopped: none for 6 s (driver.scan_timeout is 5 s)");
        assert_eq!(w.status(at(18.0), "/cell1/tracer", "SN-7", 0.0, 21).level, DiagnosticStatus::OK);
        // The rate falls to 0 once the window holds no scan.
        for s in 13..=24 {
            w.tick(at(f64::from(s)), 1, 21);
        }
        assert_eq!(w.rate(), 0.0);
    }

    #[test]
    fn no_scan_yet() {
        let t0 = Instant::now();
        let w = DriverWatch::new(t0);
        let s = w.status(t0 + Duration::from_secs(3), "/t", "", 0.0, 0);
        assert_eq!((s.level, s.message.as_str()), (DiagnosticStatus::OK, "0 publisher(s) on raw_scan; no scan yet"));
        let s = w.status(t0 + Duration::from_secs(9), "/t", "", 5.0, 0);
        assert_eq!(s.message, "no scan yet, 9 s after start (driver.scan_timeout is 5 s)");
    }
}
