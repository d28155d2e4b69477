//! The DDS participant from the ROS environment: `ROS_DOMAIN_ID`,
//! `ROS_AUTOMATIC_DISCOVERY_RANGE` and `ROS_STATIC_PEERS` with the meaning rmw_fastrtps
//! gives them (`rmw_fastrtps_shared_cpp::create_participant`):
//!
//! | range | multicast | same host | static peers | locators advertised |
//! |---|---|---|---|---|
//! | `OFF` | no | no | ignored (warning); nobody is discovered | 127.0.0.1 |
//! | `LOCALHOST` | no | yes (unicast to 127.0.0.1) | yes | 127.0.0.1, or every interface when there are static peers |
//! | `SUBNET` (default) | yes | yes | yes | every interface |
//! | `SYSTEM_DEFAULT` | yes | yes | ignored (warning) | every interface |
//!
//! A static peer is an IPv4 address or a host name (its first IPv4 address, as Fast DDS
//! takes it). The participant announces itself (SPDP) by unicast to the well-known
//! discovery port of participant ids `0..`[`STATIC_PEER_PARTICIPANT_RANGE`] at every
//! static peer, besides multicast: a ROS node on that host hears it and answers, so
//! listing a host on one side is enough (patched rustdds, `vendor/rustdds/PATCHES.md`).
//! A name that does not resolve, or an entry that is neither an address nor a host
//! name, gives one warning naming it; the others are used.

use std::collections::BTreeSet;
use std::net::{IpAddr, Ipv4Addr, ToSocketAddrs};
use std::sync::{Arc, Mutex};

use rustdds::{DomainParticipant, DomainParticipantBuilder};

use super::env::{DiscoveryRange, RosEnv};
use super::security::{Security, Strategy};

/// Participant ids probed at each static peer: how many ROS processes (DDS participants)
/// a peer host may run and still be found, the range rmw_fastrtps probes on localhost.
/// Each SPDP announcement (every 10 s) sends one datagram per id and peer.
pub const STATIC_PEER_PARTICIPANT_RANGE: u16 = 32;

/// How often the node announces itself: peers started later, and static peers, find it
/// within this; its lease is five times this, 10 s: a node killed (SIGKILL, power loss)
/// stays in peers' graphs that long. (rustdds' default: 10 s, a 50 s lease; Fast DDS':
/// 3 s, a 20 s lease.) One SPDP datagram per localhost port and static peer port.
pub const SPDP_PERIOD: std::time::Duration = std::time::Duration::from_secs(2);

/// How the participant discovers others, worked out from the environment.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DiscoveryPlan {
    /// Multicast discovery and multicast locators.
    pub multicast: bool,
    /// Announce to the other participants of this host (unicast to 127.0.0.1).
    pub same_host: bool,
    /// Whether other participants' announcements are heard at all (`OFF`: no).
    pub discover_others: bool,
    /// Advertise (and multicast on) 127.0.0.1 only.
    pub loopback_only: bool,
    /// The static peers' addresses, resolved.
    pub static_peers: Vec<Ipv4Addr>,
    /// One line per entry that could not be used, and per ignored setting.
    pub warnings: Vec<String>,
}

/// A static peer entry to an IPv4 address: an address, or a host name resolved by `lookup`
/// (its first IPv4 address).
pub fn resolve_peer(entry: &str, lookup: &dyn Fn(&str) -> std::io::Result<Vec<IpAddr>>) -> Result<Ipv4Addr, String> {
    if let Ok(ip) = entry.parse::<IpAddr>() {
        return match ip {
            IpAddr::V4(v4) => Ok(v4),
            IpAddr::V6(_) => Err(format!("static peer '{entry}': IPv6 addresses are not supported, ignored")),
        };
    }
    // Not an address: a host name (RFC 1123 labels), and not something that only looks
    // like a malformed address ("10.0.0.300", "10.0.0.1:7400").
    let is_host_name = !entry.is_empty()
        && entry.len() <= 253
        && entry.split('.').all(|label| {
            !label.is_empty()
                && label.len() <= 63
                && !label.starts_with('-')
                && !label.ends_with('-')
                && label.chars().all(|c| c.is_ascii_alphanumeric() || c == '-')
        })
        && !entry.chars().all(|c| c.is_ascii_digit() || c == '.');
    if !is_host_name {
        return Err(format!("static peer '{entry}' is neither an IPv4 address nor a host name, ignored"));
    }
    match lookup(entry) {
        Ok(addrs) => addrs
            .into_iter()
            .find_map(|a| match a {
                IpAddr::V4(v4) => Some(v4),
                IpAddr::V6(_) => None,
            })
            .ok_or_else(|| format!("static peer '{entry}' has no IPv4 address, ignored")),
        Err(e) => Err(format!("static peer '{entry}' cannot be resolved ({e}), ignored")),
    }
}

/// The system resolver (`getaddrinfo`).
pub fn system_lookup(name: &str) -> std::io::Result<Vec<IpAddr>> {
    Ok((name, 0u16).to_socket_addrs()?.map(|a| a.ip()).collect())
}

impl DiscoveryPlan {
    /// The plan for `env`, resolving static peers with `lookup`.
    pub fn new(env: &RosEnv, lookup: &dyn Fn(&str) -> std::io::Result<Vec<IpAddr>>) -> DiscoveryPlan {
        let mut warnings = Vec::new();
        let (multicast, same_host, discover_others, use_peers) = match env.discovery_range {
            DiscoveryRange::Off => (false, false, false, false),
            DiscoveryRange::Localhost => (false, true, true, true),
            DiscoveryRange::Subnet => (true, true, true, true),
            DiscoveryRange::SystemDefault => (true, true, true, false),
        };
        let mut static_peers = Vec::new();
        if use_peers {
            for entry in &env.static_peers {
                match resolve_peer(entry, lookup) {
                    Ok(ip) if !static_peers.contains(&ip) => static_peers.push(ip),
                    Ok(_) => {}
                    Err(w) => warnings.push(w),
                }
            }
        } else if !env.static_peers.is_empty() {
            let why = match env.discovery_range {
                DiscoveryRange::Off => "discovery is turned off (ROS_AUTOMATIC_DISCOVERY_RANGE=OFF)",
                _ => "discovery is left to the middleware's default (ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT)",
            };
            warnings.push(format!(
                "{} static peer(s) were specified in ROS_STATIC_PEERS, but {why}, so they are ignored",
                env.static_peers.len()
            ));
        }
        let loopback_only = match env.discovery_range {
            DiscoveryRange::Off => true,
            DiscoveryRange::Localhost => static_peers.is_empty(),
            _ => false,
        };
        DiscoveryPlan { multicast, same_host, discover_others, loopback_only, static_peers, warnings }
    }

    /// The DDS participant for `domain_id`, configured by this plan, made secure with the
    /// enclave of `security` ([`Security::Enclave`]; otherwise an open participant).
    pub fn participant(&self, domain_id: u32, security: &Security) -> Result<DomainParticipant, String> {
        let domain = u16::try_from(domain_id).map_err(|_| format!("ROS_DOMAIN_ID {domain_id} is out of range"))?;
        let mut builder = DomainParticipantBuilder::new(domain)
            .multicast(self.multicast)
            .same_host_loopback(self.same_host)
            .discover_other_participants(self.discover_others)
            .static_discovery_peers(self.static_peers.iter().copied(), STATIC_PEER_PARTICIPANT_RANGE)
            .spdp_period(SPDP_PERIOD);
        if self.loopback_only {
            builder = builder.with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)]);
        }
        if let Security::Enclave { name, dir, strategy } = security {
            builder = secure(builder, name, dir, *strategy)?;
        }
        builder.build().map_err(|e| match security {
            Security::Enclave { name, .. } => {
                format!("SECURITY ERROR: enclave '{name}': cannot create the secure DDS participant: {e:?}")
            }
            _ => format!("cannot create the DDS participant: {e:?}"),
        })
    }
}

/// The builder with DDS Security's built-in plugins (PKI-DH, access control, AES-GCM) on
/// the enclave's files (sros2's names; the private key is not password-protected).
#[cfg(feature = "security")]
fn secure(
    builder: DomainParticipantBuilder,
    name: &str,
    dir: &std::path::Path,
    _strategy: Strategy,
) -> Result<DomainParticipantBuilder, String> {
    log::info!("security: enclave '{name}' in {}", dir.display());
    crate::rmw::security::credentials::check(dir).map_err(|e| format!("SECURITY ERROR: enclave '{name}': {e}"))?;
    crate::rmw::security::mark_secure();
    Ok(builder
        .builtin_security(rustdds::DomainParticipantSecurityConfigFiles::with_ros_default_names(dir, String::new())))
}

/// Without the `security` feature no participant can be secure: under `Enforce` an enclave
/// is an error, otherwise a warning and an open participant.
#[cfg(not(feature = "security"))]
fn secure(
    builder: DomainParticipantBuilder,
    name: &str,
    _dir: &std::path::Path,
    strategy: Strategy,
) -> Result<DomainParticipantBuilder, String> {
    let why = "this build of tracer_calib has no DDS Security (cargo feature `security`)";
    match strategy {
        Strategy::Enforce => Err(format!("SECURITY ERROR: enclave '{name}': {why}")),
        Strategy::Permissive => {
            log::warn!("security is enabled (enclave '{name}'), but {why}; running without security");
            Ok(builder)
        }
    }
}

/// The participant for the process environment `env`, its warnings logged (each once),
/// secured as `security` says.
pub fn participant_from_env(env: &RosEnv, security: &Security) -> Result<DomainParticipant, String> {
    let plan = DiscoveryPlan::new(env, &system_lookup);
    for w in &plan.warnings {
        log::warn!("{w}");
    }
    if let Security::Unsecured { warning } = security {
        log::warn!("{warning}");
    }
    log::info!(
        "discovery: {:?}, multicast {}, same host {}, static peers {:?}",
        env.discovery_range,
        plan.multicast,
        plan.same_host,
        plan.static_peers
    );
    plan.participant(env.domain_id, security)
}

/// A type hash resolver: ROS type name (`pkg/msg/Name`) -> RIHS01 hash, `None` if unknown.
pub type TypeHashes = Arc<dyn Fn(&str) -> Option<String> + Send + Sync>;

/// The ROS types of the endpoints made through a context (`pkg/msg/Type`, and for a
/// service's topics, its introspection events' too, the service, `pkg/srv/Service`), as their hashes were asked for:
/// the types `~/get_type_description` answers for (rcl's type cache).
#[derive(Debug, Clone, Default)]
pub struct TypesInUse(Arc<Mutex<BTreeSet<String>>>);

impl TypesInUse {
    fn record(&self, ros_type: &str) {
        let name = match ros_type.rsplit_once('/') {
            Some((prefix, name)) if prefix.ends_with("/srv") => {
                let service = ["_Request", "_Response", "_Event"]
                    .iter()
                    .find_map(|suffix| name.strip_suffix(suffix))
                    .unwrap_or(name);
                format!("{prefix}/{service}")
            }
            _ => ros_type.to_string(),
        };
        self.0.lock().expect("types in use").insert(name);
    }

    /// A hash resolver (ROS type name -> RIHS01) over the interface layer's type hashes
    /// ([`crate::interfaces::type_hash`]) that records each type it hashed. The Zenoh
    /// session ([`super::zenoh`]) uses it too.
    pub fn hashing_resolver(&self) -> TypeHashes {
        let recorder = self.clone();
        Arc::new(move |ros_type: &str| {
            let hash = crate::interfaces::type_hash::type_hash(ros_type).ok()?;
            recorder.record(ros_type);
            Some(hash)
        })
    }

    /// The types, sorted.
    pub fn names(&self) -> Vec<String> {
        self.0.lock().expect("types in use").iter().cloned().collect()
    }
}

/// The ROS context on `participant`: every endpoint made through it (the node's topics and
/// services, rosout, parameter events, the parameter services, `ros_discovery_info`)
/// announces its type's RIHS01 hash in USER_DATA (`typehash=RIHS01_<hex>;`), as rmw does,
/// computed from the interface texts ([`crate::interfaces::type_hash`]); a type without a
/// text here announces none (patched ros2-client, `vendor/ros2-client/PATCHES.md`). The
/// types whose hashes were announced are recorded in the [`TypesInUse`].
pub fn context(participant: DomainParticipant) -> Result<(ros2_client::dds::Context, TypesInUse), String> {
    let in_use = TypesInUse::default();
    let hashes: ros2_client::context::TypeHashResolver = in_use.hashing_resolver();
    let ctx = ros2_client::dds::Context::from_domain_participant_with_type_hashes(participant, Some(hashes))
        .map_err(|e| format!("cannot create the ROS context: {e:?}"))?;
    Ok((ctx, in_use))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env(range: DiscoveryRange, peers: &[&str]) -> RosEnv {
        RosEnv {
            domain_id: 0,
            discovery_range: range,
            static_peers: peers.iter().map(|s| s.to_string()).collect(),
            warnings: vec![],
            security: Default::default(),
            middleware: crate::rmw::Middleware::Dds,
        }
    }

    fn lookup(name: &str) -> std::io::Result<Vec<IpAddr>> {
        match name {
            "tracer-b" => Ok(vec!["fe80::1".parse().unwrap(), "10.213.0.2".parse().unwrap()]),
            "v6only" => Ok(vec!["fe80::1".parse().unwrap()]),
            _ => Err(std::io::Error::other("Name or service not known")),
        }
    }

    #[test]
    fn ranges_as_rmw_fastrtps() {
        let p = DiscoveryPlan::new(&env(DiscoveryRange::Subnet, &["10.213.0.2"]), &lookup);
        assert!(p.multicast && p.same_host && p.discover_others && !p.loopback_only);
        assert_eq!(p.static_peers, vec![Ipv4Addr::new(10, 213, 0, 2)]);

        let p = DiscoveryPlan::new(&env(DiscoveryRange::Localhost, &[]), &lookup);
        assert!(!p.multicast && p.same_host && p.discover_others && p.loopback_only);
        let p = DiscoveryPlan::new(&env(DiscoveryRange::Localhost, &["10.213.0.2"]), &lookup);
        assert!(!p.multicast && !p.loopback_only, "a static peer must reach the advertised locators");
        assert_eq!(p.static_peers.len(), 1);

        let p = DiscoveryPlan::new(&env(DiscoveryRange::Off, &[]), &lookup);
        assert!(!p.multicast && !p.same_host && !p.discover_others && p.loopback_only);
        assert!(p.warnings.is_empty());
        let p = DiscoveryPlan::new(&env(DiscoveryRange::Off, &["10.213.0.2"]), &lookup);
        assert!(p.static_peers.is_empty());
        assert_eq!(p.warnings.len(), 1);
        assert!(p.warnings[0].contains("turned off"), "{:?}", p.warnings);

        let p = DiscoveryPlan::new(&env(DiscoveryRange::SystemDefault, &["10.213.0.2"]), &lookup);
        assert!(p.multicast && p.static_peers.is_empty());
        assert!(p.warnings[0].contains("SYSTEM_DEFAULT"), "{:?}", p.warnings);
    }

    #[test]
    fn bad_peers_warn_once_each_and_the_others_are_used() {
        let peers =
            ["10.213.0.2", "no-such-host.invalid", "10.0.0.300", "10.213.0.3:7400", "tracer-b", "v6only", "::1"];
        let p = DiscoveryPlan::new(&env(DiscoveryRange::Subnet, &peers), &lookup);
        assert_eq!(p.static_peers, vec![Ipv4Addr::new(10, 213, 0, 2)], "tracer-b is the same address");
        assert_eq!(p.warnings.len(), 5, "{:?}", p.warnings);
        for (w, name) in
            p.warnings.iter().zip(["no-such-host.invalid", "10.0.0.300", "10.213.0.3:7400", "v6only", "::1"])
        {
            assert!(w.contains(&format!("'{name}'")), "{w}");
        }
        assert!(p.warnings[0].contains("cannot be resolved"));
        assert!(p.warnings[1].contains("neither"));
    }

    #[test]
    fn host_names_resolve_to_their_first_ipv4_address() {
        assert_eq!(resolve_peer("tracer-b", &lookup), Ok(Ipv4Addr::new(10, 213, 0, 2)));
        assert_eq!(resolve_peer("127.0.0.1", &lookup), Ok(Ipv4Addr::LOCALHOST));
        assert!(resolve_peer("-bad-.x", &lookup).is_err());
        assert!(resolve_peer("a b", &lookup).is_err());
    }
}
