//! The Zenoh session a process joins under `RMW_IMPLEMENTATION=rmw_zenoh_cpp`, configured
//! as rmw_zenoh_cpp (0.2.10, `zenoh_config.cpp`, `rmw_context_impl_s.cpp`) configures it:
//!
//! - the session configuration is the file `ZENOH_SESSION_CONFIG_URI` names, else
//!   rmw_zenoh's default ([`DEFAULT_SESSION_CONFIG`], embedded: peer mode, connect to the
//!   router at `tcp/localhost:7447`, listen on `tcp/localhost:0`, no multicast scouting,
//!   gossip through the router);
//!   One departure, on the embedded default only ([`NODE_DEFAULTS`]): the transmission
//!   queue of the data priority holds 16 batches, not 2. A contour is ~16 kB; two 64 kB
//!   batches hold about eight, and a reliable KEEP_LAST sample is pushed with congestion
//!   control `Drop` (as rmw_zenoh maps it), dropped 1 ms after the queue is full. On a
//!   lossy link TCP stalls for its retransmission timeout (200 ms, doubling when lost
//!   again): under 25 % segment loss the node dropped contours before they reached the
//!   wire (seen in a capture: never sent) in 3 of 13 runs, with 16 batches once in 13
//!   (one contour). The batches are allocated only when needed (`allocation: lazy`);
//!   a file of the user's own is taken as it is;
//! - `ZENOH_CONFIG_OVERRIDE` (`key=json5;key=json5`) is applied on top, a pair that does
//!   not apply warned about and ignored;
//! - `ZENOH_ROUTER_CHECK_ATTEMPTS` (unset: 1; `n > 0`: n checks a second apart; 0: until
//!   a router answers; `< 0`: no check) says how long the router is waited for. Where
//!   rmw_zenoh then goes on without a router, the node stops with one line naming the
//!   endpoints: a tracer whose contours reach nobody is a failure the cell must see at
//!   once, not a silent one (a router-less set-up sets a negative count);
//! - the ROS domain is the first chunk of every key expression, not a transport setting.
//!
//! The protocol itself (liveliness tokens, key expressions with type hashes,
//! attachments, queryables) is ros2-client's Zenoh backend, fed the hashes of the
//! node's types ([`crate::interfaces::type_hash`]; `vendor/ros2-client/PATCHES.md`).

use std::time::Duration;

use log::warn;
use ros2_client::zenoh::{Context, ContextOptions};
use zenoh::Wait;

/// rmw_zenoh_cpp's default session configuration
/// (`rmw_zenoh_cpp/config/DEFAULT_RMW_ZENOH_SESSION_CONFIG.json5`, 0.2.10, Apache-2.0).
pub const DEFAULT_SESSION_CONFIG: &str = include_str!("zenoh_session_config.json5");

/// What the node sets on top of [`DEFAULT_SESSION_CONFIG`] when no file is named (the
/// module doc says why): `(key, json5 value)`.
pub const NODE_DEFAULTS: &[(&str, &str)] = &[("transport/link/tx/queue/size/data", "16")];

/// How long to wait for a router (`ZENOH_ROUTER_CHECK_ATTEMPTS`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RouterCheck {
    /// Check this many times, a second apart.
    Attempts(u64),
    /// Check until a router answers.
    Forever,
    /// Do not check.
    Skip,
}

impl RouterCheck {
    /// `ZENOH_ROUTER_CHECK_ATTEMPTS` as rmw_zenoh reads it (`strtoll` base 10, so text
    /// that is no number reads as 0: forever).
    pub fn from_value(value: Option<&str>) -> RouterCheck {
        match value.filter(|v| !v.is_empty()) {
            None => RouterCheck::Attempts(1),
            Some(v) => match crate::c_number::strtoll_prefix(v) {
                n if n > 0 => RouterCheck::Attempts(n as u64),
                n if n < 0 => RouterCheck::Skip,
                _ => RouterCheck::Forever,
            },
        }
    }
}

/// The Zenoh variables of the environment.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ZenohEnv {
    /// `ZENOH_SESSION_CONFIG_URI`.
    pub config_uri: Option<String>,
    /// `ZENOH_CONFIG_OVERRIDE`.
    pub config_override: Option<String>,
    /// `ZENOH_ROUTER_CHECK_ATTEMPTS`.
    pub router_check_attempts: Option<String>,
}

impl ZenohEnv {
    /// Reads the variables through `get` (name -> value).
    pub fn from_lookup(get: impl Fn(&str) -> Option<String>) -> ZenohEnv {
        ZenohEnv {
            config_uri: get("ZENOH_SESSION_CONFIG_URI"),
            config_override: get("ZENOH_CONFIG_OVERRIDE"),
            router_check_attempts: get("ZENOH_ROUTER_CHECK_ATTEMPTS"),
        }
    }

    /// Reads the process environment.
    pub fn from_env() -> ZenohEnv {
        ZenohEnv::from_lookup(|name| std::env::var_os(name).map(|v| v.to_string_lossy().into_owned()))
    }

    /// The session configuration: the file, or rmw_zenoh's default with
    /// [`NODE_DEFAULTS`], with the overrides. Returns it with the warnings for the
    /// override pairs that did not apply.
    pub fn session_config(&self) -> Result<(zenoh::Config, Vec<String>), String> {
        let mut config = match self.config_uri.as_deref().filter(|u| !u.is_empty()) {
            Some(uri) => zenoh::Config::from_file(uri)
                .map_err(|e| format!("ZENOH_SESSION_CONFIG_URI: invalid Zenoh configuration file {uri}: {e}"))?,
            None => {
                let mut config = zenoh::Config::from_json5(DEFAULT_SESSION_CONFIG)
                    .map_err(|e| format!("rmw_zenoh's default session configuration does not load: {e}"))?;
                for (key, value) in NODE_DEFAULTS {
                    config
                        .insert_json5(key, value)
                        .map_err(|e| format!("the node's Zenoh default {key}={value} does not apply: {e}"))?;
                }
                config
            }
        };
        let mut warnings = Vec::new();
        for pair in self.config_override.as_deref().unwrap_or("").split(';') {
            // rmw_zenoh: `getline(key, '=')` then the rest of the line; a pair without
            // both is skipped.
            let Some((key, value)) = pair.split_once('=') else { continue };
            if key.is_empty() || value.is_empty() {
                continue;
            }
            if let Err(e) = config.insert_json5(key, value) {
                warnings.push(format!(
                    "ZENOH_CONFIG_OVERRIDE: ignoring the invalid configuration key-value pair ({key}, {value}): {e}"
                ));
            }
        }
        Ok((config, warnings))
    }
}

/// The endpoints a configuration connects to, for messages (`tcp/localhost:7447`).
fn connect_endpoints(config: &zenoh::Config) -> String {
    match config.get_json("connect/endpoints") {
        Ok(json) => match serde_json::from_str::<serde_json::Value>(&json) {
            Ok(serde_json::Value::Array(a)) if !a.is_empty() => a
                .iter()
                .map(|e| e.as_str().map(str::to_string).unwrap_or_else(|| e.to_string()))
                .collect::<Vec<_>>()
                .join(", "),
            _ => json,
        },
        Err(_) => "no endpoint (connect/endpoints is empty)".to_string(),
    }
}

/// Opens the session (domain `domain_id`, the node's types hashed by `type_hashes`) and
/// waits for the router as `ZENOH_ROUTER_CHECK_ATTEMPTS` says.
pub fn context(env: &ZenohEnv, domain_id: u32, type_hashes: super::dds::TypeHashes) -> Result<Context, String> {
    let (config, warnings) = env.session_config()?;
    for w in warnings {
        warn!("{w}");
    }
    let endpoints = connect_endpoints(&config);
    let domain = u16::try_from(domain_id).map_err(|_| format!("ROS_DOMAIN_ID {domain_id} is out of range"))?;
    let ctx =
        Context::with_options(ContextOptions::new().domain_id(domain).zenoh_config(config).type_hashes(type_hashes))
            .map_err(|e| format!("cannot open the Zenoh session (connect to {endpoints}): {e}"))?;
    let check = RouterCheck::from_value(env.router_check_attempts.as_deref());
    let attempts = match check {
        RouterCheck::Skip => return Ok(ctx),
        RouterCheck::Attempts(n) => n,
        RouterCheck::Forever => u64::MAX,
    };
    let mut made = 0u64;
    loop {
        if ctx.session().info().routers_zid().wait().next().is_some() {
            return Ok(ctx);
        }
        made += 1;
        if made >= attempts {
            return Err(format!(
                "no Zenoh router at {endpoints} after {made} attempt(s) (ZENOH_ROUTER_CHECK_ATTEMPTS; \
                 start one with `ros2 run rmw_zenoh_cpp rmw_zenohd`)"
            ));
        }
        if made == 1 {
            warn!("Unable to connect to a Zenoh router at {endpoints}; retrying (ZENOH_ROUTER_CHECK_ATTEMPTS)");
        }
        std::thread::sleep(Duration::from_secs(1));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    #[test]
    fn router_check_attempts_as_rmw_zenoh() {
        assert_eq!(RouterCheck::from_value(None), RouterCheck::Attempts(1));
        assert_eq!(RouterCheck::from_value(Some("")), RouterCheck::Attempts(1));
        assert_eq!(RouterCheck::from_value(Some("5")), RouterCheck::Attempts(5));
        assert_eq!(RouterCheck::from_value(Some(" 3x")), RouterCheck::Attempts(3));
        assert_eq!(RouterCheck::from_value(Some("0")), RouterCheck::Forever);
        assert_eq!(RouterCheck::from_value(Some("abc")), RouterCheck::Forever);
        assert_eq!(RouterCheck::from_value(Some("-1")), RouterCheck::Skip);
    }

    #[test]
    fn default_config_is_rmw_zenohs() {
        let (config, warnings) = ZenohEnv::default().session_config().unwrap();
        assert!(warnings.is_empty());
        assert_eq!(connect_endpoints(&config), "tcp/localhost:7447");
        assert_eq!(config.get_json("mode").unwrap(), "\"peer\"");
        assert_eq!(config.get_json("scouting/multicast/enabled").unwrap(), "false");
        assert_eq!(config.get_json("listen/endpoints").unwrap(), "[\"tcp/localhost:0\"]");
        // The node's one departure, and rmw_zenoh's value beside it.
        assert_eq!(config.get_json("transport/link/tx/queue/size/data").unwrap(), "16");
        assert_eq!(config.get_json("transport/link/tx/queue/size/data_high").unwrap(), "2");
    }

    #[test]
    fn overrides_apply_and_bad_pairs_warn() {
        let env = ZenohEnv {
            config_override: Some(
                "connect/endpoints=[\"tcp/127.0.0.1:7450\"];nonsense;mode=\"client\";no/such/key=1".into(),
            ),
            ..ZenohEnv::default()
        };
        let (config, warnings) = env.session_config().unwrap();
        assert_eq!(connect_endpoints(&config), "tcp/127.0.0.1:7450");
        assert_eq!(config.get_json("mode").unwrap(), "\"client\"");
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(warnings[0].contains("no/such/key"), "{warnings:?}");
    }

    #[test]
    fn a_users_file_is_taken_as_it_is_and_overrides_win() {
        let path = std::env::temp_dir().join(format!("tracer_calib_zenoh_{}.json5", std::process::id()));
        std::fs::write(&path, DEFAULT_SESSION_CONFIG).unwrap();
        let env = ZenohEnv { config_uri: Some(path.to_string_lossy().into_owned()), ..ZenohEnv::default() };
        let (config, _) = env.session_config().unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(config.get_json("transport/link/tx/queue/size/data").unwrap(), "2");
        let env =
            ZenohEnv { config_override: Some("transport/link/tx/queue/size/data=4".into()), ..ZenohEnv::default() };
        let (config, warnings) = env.session_config().unwrap();
        assert!(warnings.is_empty(), "{warnings:?}");
        assert_eq!(config.get_json("transport/link/tx/queue/size/data").unwrap(), "4");
    }

    #[test]
    fn a_missing_config_file_is_named() {
        let env = ZenohEnv { config_uri: Some("/nonexistent/zenoh.json5".into()), ..ZenohEnv::default() };
        let err = env.session_config().unwrap_err();
        assert!(
            err.starts_with("ZENOH_SESSION_CONFIG_URI: invalid Zenoh configuration file /nonexistent/zenoh.json5"),
            "{err}"
        );
    }

    #[test]
    fn no_router_stops_with_one_line_naming_the_endpoint() {
        // A port nothing listens on (the session does not listen: no traffic leaves
        // loopback, nothing is reachable).
        let env = ZenohEnv {
            config_override: Some("connect/endpoints=[\"tcp/127.0.0.1:9\"];listen/endpoints=[]".into()),
            router_check_attempts: Some("2".into()),
            ..ZenohEnv::default()
        };
        let started = std::time::Instant::now();
        let err = context(&env, 0, Arc::new(|_| None)).err().expect("no router: an error");
        assert!(err.contains("tcp/127.0.0.1:9") && err.contains("after 2 attempt(s)"), "{err}");
        assert!(!err.contains('\n'));
        assert!(started.elapsed() >= Duration::from_secs(1), "one second between attempts");
    }
}
