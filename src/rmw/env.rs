//! The ROS environment of a process: what a stock node reads to join its graph.
//!
//! [`RosEnv`] reads `ROS_DOMAIN_ID` (0..=232), `ROS_AUTOMATIC_DISCOVERY_RANGE` (an unknown value
//! means localhost, as in rcl), the deprecated `ROS_LOCALHOST_ONLY=1` (honoured, as in Jazzy) and
//! `ROS_STATIC_PEERS`, and the SROS2 variables (`ROS_SECURITY_*`, resolved by
//! [`super::security`]).

use super::implementation::{Middleware, UnknownImplementation};
use super::security::SecurityEnv;
use crate::c_number;

/// An unusable ROS environment variable.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum EnvError {
    /// `ROS_DOMAIN_ID` is not an integer in `0..=232`.
    #[error("ROS_DOMAIN_ID must be an integer in 0..={max}, got '{0}'", max = ROS_DOMAIN_ID_MAX)]
    DomainId(String),
    /// `RMW_IMPLEMENTATION` names a middleware the node does not speak.
    #[error(transparent)]
    Implementation(#[from] UnknownImplementation),
}

/// The largest `ROS_DOMAIN_ID` the RTPS port mapping allows.
pub const ROS_DOMAIN_ID_MAX: u32 = 232;

/// `ROS_AUTOMATIC_DISCOVERY_RANGE`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DiscoveryRange {
    /// `OFF`: no discovery at all (static peers are ignored, as rmw_fastrtps does).
    Off,
    /// `LOCALHOST`: only participants on this host.
    Localhost,
    /// `SUBNET`: the DDS default, multicast on the local networks. Also the default when unset.
    Subnet,
    /// `SYSTEM_DEFAULT`: whatever the middleware does by default.
    SystemDefault,
}

impl DiscoveryRange {
    /// Whether automatic discovery stays on this host (`LOCALHOST`, and `OFF`, which
    /// discovers nothing). What each range does: [`crate::rmw::dds`].
    pub fn is_local_only(self) -> bool {
        matches!(self, DiscoveryRange::Off | DiscoveryRange::Localhost)
    }
}

/// The ROS environment of the process.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RosEnv {
    /// `ROS_DOMAIN_ID`, 0 when unset or empty.
    pub domain_id: u32,
    /// `ROS_AUTOMATIC_DISCOVERY_RANGE` (or `ROS_LOCALHOST_ONLY=1`).
    pub discovery_range: DiscoveryRange,
    /// `ROS_STATIC_PEERS`, split at `;`, empty entries dropped.
    pub static_peers: Vec<String>,
    /// Things to log as warnings (an unknown discovery range, a deprecated variable).
    pub warnings: Vec<String>,
    /// `ROS_SECURITY_ENABLE`, `ROS_SECURITY_STRATEGY`, `ROS_SECURITY_KEYSTORE`,
    /// `ROS_SECURITY_ENCLAVE_OVERRIDE`, as given.
    pub security: SecurityEnv,
    /// `RMW_IMPLEMENTATION`: DDS or Zenoh ([`super::implementation`]).
    pub middleware: Middleware,
}

/// `ROS_DOMAIN_ID`: unset or empty -> 0; else an integer (C `strtoul` base 0 forms: `7`,
/// `0x1f`, `010` = 8) in `0..=232`, surrounding whitespace ignored.
pub fn parse_domain_id(value: Option<&str>) -> Result<u32, EnvError> {
    let Some(text) = value.map(str::trim).filter(|t| !t.is_empty()) else {
        return Ok(0);
    };
    match c_number::strtoll(text).and_then(|v| u32::try_from(v).ok()) {
        Some(id) if id <= ROS_DOMAIN_ID_MAX && !text.starts_with(['-', '+']) => Ok(id),
        _ => Err(EnvError::DomainId(value.unwrap_or_default().to_string())),
    }
}

/// `ROS_AUTOMATIC_DISCOVERY_RANGE`: unset or empty -> `Subnet`; `OFF`, `LOCALHOST`, `SUBNET`,
/// `SYSTEM_DEFAULT` (exact case); anything else -> `Localhost` with a warning, as rcl does.
pub fn parse_discovery_range(value: Option<&str>) -> (DiscoveryRange, Option<String>) {
    match value.unwrap_or("") {
        "" | "SUBNET" => (DiscoveryRange::Subnet, None),
        "OFF" => (DiscoveryRange::Off, None),
        "LOCALHOST" => (DiscoveryRange::Localhost, None),
        "SYSTEM_DEFAULT" => (DiscoveryRange::SystemDefault, None),
        other => (
            DiscoveryRange::Localhost,
            Some(format!(
                "Invalid value '{other}' specified for 'ROS_AUTOMATIC_DISCOVERY_RANGE', assuming localhost only"
            )),
        ),
    }
}

impl RosEnv {
    /// Reads the variables through `get` (name -> value), so it can be tested without touching
    /// the process environment.
    pub fn from_lookup(get: impl Fn(&str) -> Option<String>) -> Result<RosEnv, EnvError> {
        let domain_id = parse_domain_id(get("ROS_DOMAIN_ID").as_deref())?;
        let (mut discovery_range, warning) = parse_discovery_range(get("ROS_AUTOMATIC_DISCOVERY_RANGE").as_deref());
        let mut warnings: Vec<String> = warning.into_iter().collect();
        let mut static_peers: Vec<String> = get("ROS_STATIC_PEERS")
            .unwrap_or_default()
            .split(';')
            .map(str::trim)
            .filter(|p| !p.is_empty())
            .map(str::to_string)
            .collect();
        if get("ROS_LOCALHOST_ONLY").as_deref().map(str::trim) == Some("1") {
            warnings.push(
                "ROS_LOCALHOST_ONLY is deprecated but still honored if it is enabled; \
                 use ROS_AUTOMATIC_DISCOVERY_RANGE and ROS_STATIC_PEERS instead"
                    .to_string(),
            );
            discovery_range = DiscoveryRange::Localhost;
            static_peers.clear();
        }
        let security = SecurityEnv::from_lookup(&get);
        let middleware = Middleware::from_rmw_implementation(get("RMW_IMPLEMENTATION").as_deref())?;
        Ok(RosEnv { domain_id, discovery_range, static_peers, warnings, security, middleware })
    }

    /// Reads the real process environment.
    pub fn from_env() -> Result<RosEnv, EnvError> {
        RosEnv::from_lookup(|name| std::env::var_os(name).map(|v| v.to_string_lossy().into_owned()))
    }
}

// ------------------------------------------------------------------------------------------

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    // ------------------------------------------------------------ environment

    fn env(vars: &[(&str, &str)]) -> Result<RosEnv, EnvError> {
        let map: HashMap<String, String> = vars.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
        RosEnv::from_lookup(|k| map.get(k).cloned())
    }

    #[test]
    fn domain_id() {
        assert_eq!(parse_domain_id(None), Ok(0));
        assert_eq!(parse_domain_id(Some("")), Ok(0));
        assert_eq!(parse_domain_id(Some("0")), Ok(0));
        assert_eq!(parse_domain_id(Some("42")), Ok(42));
        assert_eq!(parse_domain_id(Some(" 7 ")), Ok(7));
        assert_eq!(parse_domain_id(Some("232")), Ok(232));
        assert_eq!(parse_domain_id(Some("0x10")), Ok(16));
        for bad in ["233", "-1", "+5", "abc", "12abc", "1.5", "99999999999999999999"] {
            assert_eq!(parse_domain_id(Some(bad)), Err(EnvError::DomainId(bad.into())), "{bad}");
        }
        assert_eq!(
            EnvError::DomainId("300".into()).to_string(),
            "ROS_DOMAIN_ID must be an integer in 0..=232, got '300'"
        );
    }

    #[test]
    fn discovery_range() {
        assert_eq!(parse_discovery_range(None), (DiscoveryRange::Subnet, None));
        assert_eq!(parse_discovery_range(Some("")), (DiscoveryRange::Subnet, None));
        assert_eq!(parse_discovery_range(Some("LOCALHOST")), (DiscoveryRange::Localhost, None));
        assert_eq!(parse_discovery_range(Some("SUBNET")), (DiscoveryRange::Subnet, None));
        assert_eq!(parse_discovery_range(Some("OFF")), (DiscoveryRange::Off, None));
        assert_eq!(parse_discovery_range(Some("SYSTEM_DEFAULT")), (DiscoveryRange::SystemDefault, None));
        let (range, warning) = parse_discovery_range(Some("localhost"));
        assert_eq!(range, DiscoveryRange::Localhost, "unknown values are the safe choice");
        assert!(warning.unwrap().contains("'localhost'"));
        assert!(DiscoveryRange::Localhost.is_local_only() && DiscoveryRange::Off.is_local_only());
        assert!(!DiscoveryRange::Subnet.is_local_only() && !DiscoveryRange::SystemDefault.is_local_only());
    }

    #[test]
    fn ros_env_from_values() {
        let e = env(&[]).unwrap();
        assert_eq!(
            e,
            RosEnv {
                domain_id: 0,
                discovery_range: DiscoveryRange::Subnet,
                static_peers: vec![],
                warnings: vec![],
                security: SecurityEnv::default(),
                middleware: Middleware::Dds,
            }
        );
        let e = env(&[
            ("ROS_DOMAIN_ID", "17"),
            ("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST"),
            ("ROS_STATIC_PEERS", "192.168.0.2; host.example;;"),
        ])
        .unwrap();
        assert_eq!(e.domain_id, 17);
        assert_eq!(e.discovery_range, DiscoveryRange::Localhost);
        assert_eq!(e.static_peers, vec!["192.168.0.2", "host.example"]);
        assert!(e.warnings.is_empty());
        let e = env(&[("ROS_LOCALHOST_ONLY", "1"), ("ROS_AUTOMATIC_DISCOVERY_RANGE", "SUBNET")]).unwrap();
        assert_eq!(e.discovery_range, DiscoveryRange::Localhost);
        assert_eq!(e.warnings.len(), 1);
        let e = env(&[("ROS_LOCALHOST_ONLY", "0")]).unwrap();
        assert_eq!(e.discovery_range, DiscoveryRange::Subnet);
        assert!(env(&[("ROS_DOMAIN_ID", "500")]).is_err());
        assert_eq!(env(&[("RMW_IMPLEMENTATION", "rmw_zenoh_cpp")]).unwrap().middleware, Middleware::Zenoh);
        assert!(matches!(env(&[("RMW_IMPLEMENTATION", "rmw_opendds")]), Err(EnvError::Implementation(_))));
        // the real environment reads without panicking
        let _ = RosEnv::from_env();
    }
}
