//! SROS2: which enclave the process uses, read as rcl reads it.
//!
//! rcl (`rcl/src/rcl/security.c`, `rcl_get_security_options_from_environment`):
//!
//! - `ROS_SECURITY_ENABLE`: security is on only when it is exactly `true`;
//! - `ROS_SECURITY_STRATEGY`: exactly `Enforce` enforces, anything else is permissive;
//! - the enclave name is `--ros-args --enclave NAME` (`-e`), else `/`; it must be a valid
//!   absolute name (`rcl_validate_enclave_name`), checked whether or not security is on;
//! - `ROS_SECURITY_KEYSTORE` (unset or empty: no enclave found) is the keystore;
//!   `ROS_SECURITY_ENCLAVE_OVERRIDE`, when not empty, replaces the enclave name;
//! - the enclave folder is `KEYSTORE/enclaves` for `/`, else `KEYSTORE/enclaves/` + the
//!   name without its first character (`exact_match_lookup`); it must be a directory.
//!
//! Then, as rmw does (`rmw_dds_common::get_security_files`), the folder must hold the six
//! files `ros2 security create_enclave` writes: `identity_ca.cert.pem`, `cert.pem`,
//! `key.pem`, `permissions_ca.cert.pem`, `governance.p7s`, `permissions.p7s`; here they
//! must also be readable.
//!
//! No enclave (no keystore, no folder, a file missing or unreadable): under `Enforce` the
//! process must not start ([`SecurityError`], one line naming the enclave and the reason);
//! otherwise it runs unsecured, with a warning.
//!
//! Found, the enclave's credentials are checked before the participant is made (with the
//! `security` feature: [`credentials`]): an expired certificate or one of another CA, a
//! key that is not the certificate's, a permissions or governance document whose signature
//! does not verify with the permissions CA stop the process with one line naming the file
//! and the reason, whatever the strategy (as rmw fails to make such a participant).

use std::path::{Path, PathBuf};

use crate::names::validate_namespace;

#[cfg(feature = "security")]
pub mod credentials;

/// A secure participant was made in this process ([`mark_secure`]).
static SECURE: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Records that this process has a secure participant (so [`peers_refused_authentication`]
/// reports).
pub fn mark_secure() {
    SECURE.store(true, std::sync::atomic::Ordering::Relaxed);
}

/// With a secure participant in this process: how many remote participants failed
/// authentication (a certificate of another CA or expired, a handshake whose signature
/// does not verify), each counted once (rustdds' count, a tracer_calib patch). `None`
/// without one (security off: nothing to report, `/diagnostics` as before).
pub fn peers_refused_authentication() -> Option<u64> {
    if !SECURE.load(std::sync::atomic::Ordering::Relaxed) {
        return None;
    }
    #[cfg(feature = "security")]
    return Some(rustdds::remote_participants_refused_authentication());
    #[cfg(not(feature = "security"))]
    None
}

/// The files an enclave folder must hold (rmw_dds_common's names).
pub const ENCLAVE_FILES: [&str; 6] =
    ["identity_ca.cert.pem", "cert.pem", "key.pem", "permissions_ca.cert.pem", "governance.p7s", "permissions.p7s"];

/// `ROS_SECURITY_STRATEGY`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Strategy {
    /// `Enforce`: no enclave, no process.
    Enforce,
    /// Anything else (rcl's default): no enclave, an unsecured process.
    Permissive,
}

/// The security variables of the environment, as given (rcl reads them at init).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct SecurityEnv {
    /// `ROS_SECURITY_ENABLE`, unset -> `None`.
    pub enable: Option<String>,
    /// `ROS_SECURITY_STRATEGY`.
    pub strategy: Option<String>,
    /// `ROS_SECURITY_KEYSTORE`.
    pub keystore: Option<String>,
    /// `ROS_SECURITY_ENCLAVE_OVERRIDE`.
    pub enclave_override: Option<String>,
}

impl SecurityEnv {
    /// Reads the four variables through `get`.
    pub fn from_lookup(get: &impl Fn(&str) -> Option<String>) -> SecurityEnv {
        SecurityEnv {
            enable: get("ROS_SECURITY_ENABLE"),
            strategy: get("ROS_SECURITY_STRATEGY"),
            keystore: get("ROS_SECURITY_KEYSTORE"),
            enclave_override: get("ROS_SECURITY_ENCLAVE_OVERRIDE"),
        }
    }

    /// Security is on: `ROS_SECURITY_ENABLE` is exactly `true`.
    pub fn enabled(&self) -> bool {
        self.enable.as_deref() == Some("true")
    }

    /// `Enforce` exactly, else permissive.
    pub fn strategy(&self) -> Strategy {
        if self.strategy.as_deref() == Some("Enforce") { Strategy::Enforce } else { Strategy::Permissive }
    }
}

/// What the participant does about security.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Security {
    /// Security is off (`ROS_SECURITY_ENABLE` is not `true`): today's participant.
    Off,
    /// Secure, with this enclave.
    Enclave {
        /// The enclave name looked up (the override if given, else `--enclave`, else `/`).
        name: String,
        /// Its folder, holding [`ENCLAVE_FILES`].
        dir: PathBuf,
        /// The strategy (what to do if the participant cannot be made secure).
        strategy: Strategy,
    },
    /// Security is on but permissive and no usable enclave was found: unsecured, and this
    /// warning is logged.
    Unsecured { warning: String },
}

/// Why an enforcing process must not start: one line, naming the enclave and the reason.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("SECURITY ERROR: enclave '{enclave}': {reason}")]
pub struct SecurityError {
    pub enclave: String,
    pub reason: String,
}

/// The enclave folder for `name` in `keystore` (rcl's `exact_match_lookup`): `/` ->
/// `KEYSTORE/enclaves`, else `KEYSTORE/enclaves/` joined with the name less its first
/// character.
pub fn enclave_dir(keystore: &Path, name: &str) -> PathBuf {
    let enclaves = keystore.join("enclaves");
    if name == "/" {
        return enclaves;
    }
    let rest = name.get(1..).unwrap_or("");
    rest.split('/').filter(|p| !p.is_empty()).fold(enclaves, |dir, part| dir.join(part))
}

/// Works out [`Security`] from the environment and the `--enclave` argument. `Err`: the
/// enclave name is invalid (rcl fails init whatever the settings), or the strategy is
/// `Enforce` and no usable enclave was found.
pub fn resolve(env: &SecurityEnv, enclave_arg: Option<&str>) -> Result<Security, SecurityError> {
    let name = enclave_arg.unwrap_or("/");
    if let Err(e) = validate_namespace(name) {
        return Err(SecurityError { enclave: name.to_string(), reason: format!("not a valid enclave name: {e}") });
    }
    if !env.enabled() {
        return Ok(Security::Off);
    }
    let strategy = env.strategy();
    let lookup = env.enclave_override.as_deref().filter(|o| !o.is_empty()).unwrap_or(name).to_string();
    let found = match env.keystore.as_deref().filter(|k| !k.is_empty()) {
        None => Err("ROS_SECURITY_KEYSTORE is not set".to_string()),
        Some(keystore) => {
            let dir = enclave_dir(Path::new(keystore), &lookup);
            check_enclave_dir(&dir).map(|()| dir)
        }
    };
    match (found, strategy) {
        (Ok(dir), _) => Ok(Security::Enclave { name: lookup, dir, strategy }),
        (Err(reason), Strategy::Enforce) => Err(SecurityError { enclave: lookup, reason }),
        (Err(reason), Strategy::Permissive) => Ok(Security::Unsecured {
            warning: format!(
                "security is enabled but enclave '{lookup}' cannot be used ({reason}); \
                 ROS_SECURITY_STRATEGY is not Enforce, so running without security"
            ),
        }),
    }
}

/// The folder is a directory and every file of [`ENCLAVE_FILES`] in it can be read.
fn check_enclave_dir(dir: &Path) -> Result<(), String> {
    if !dir.is_dir() {
        return Err(format!("directory '{}' does not exist", dir.display()));
    }
    for name in ENCLAVE_FILES {
        let file = dir.join(name);
        if let Err(e) = std::fs::File::open(&file) {
            let what = if e.kind() == std::io::ErrorKind::NotFound {
                "is missing".to_string()
            } else {
                format!("cannot be read: {e}")
            };
            return Err(format!("'{}' {what}", file.display()));
        }
    }
    Ok(())
}

// ------------------------------------------------------------------------------------------

#[cfg(test)]
mod tests {
    use super::*;

    fn env(enable: &str, strategy: &str, keystore: Option<&Path>, over: Option<&str>) -> SecurityEnv {
        SecurityEnv {
            enable: Some(enable.to_string()),
            strategy: Some(strategy.to_string()),
            keystore: keystore.map(|k| k.display().to_string()),
            enclave_override: over.map(str::to_string),
        }
    }

    /// A keystore with enclaves `/tracer` and `/cell1/hmi` (the six files, empty) and a
    /// root enclave, in a scratch folder.
    fn keystore(tag: &str) -> PathBuf {
        let ks = std::env::temp_dir().join(format!("tracer_calib_sec_{}_{tag}", std::process::id()));
        let _ = std::fs::remove_dir_all(&ks);
        for e in ["enclaves/tracer", "enclaves/cell1/hmi", "enclaves"] {
            let dir = ks.join(e);
            std::fs::create_dir_all(&dir).unwrap();
            for f in ENCLAVE_FILES {
                std::fs::write(dir.join(f), b"x").unwrap();
            }
        }
        ks
    }

    #[test]
    fn enable_and_strategy_are_exact() {
        let mut e = SecurityEnv::default();
        assert!(!e.enabled());
        for (v, on) in [("true", true), ("True", false), ("1", false), ("TRUE", false), ("", false), ("false", false)] {
            e.enable = Some(v.into());
            assert_eq!(e.enabled(), on, "{v}");
        }
        for (v, s) in
            [("Enforce", Strategy::Enforce), ("enforce", Strategy::Permissive), ("Permissive", Strategy::Permissive)]
        {
            e.strategy = Some(v.into());
            assert_eq!(e.strategy(), s, "{v}");
        }
        e.strategy = None;
        assert_eq!(e.strategy(), Strategy::Permissive);
        let looked = SecurityEnv::from_lookup(&|k: &str| Some(format!("v_{k}")));
        assert_eq!(looked.keystore.as_deref(), Some("v_ROS_SECURITY_KEYSTORE"));
        assert_eq!(looked.enclave_override.as_deref(), Some("v_ROS_SECURITY_ENCLAVE_OVERRIDE"));
    }

    #[test]
    fn enclave_dirs() {
        let ks = Path::new("/ks");
        assert_eq!(enclave_dir(ks, "/"), Path::new("/ks/enclaves"));
        assert_eq!(enclave_dir(ks, "/tracer"), Path::new("/ks/enclaves/tracer"));
        assert_eq!(enclave_dir(ks, "/cell1/hmi"), Path::new("/ks/enclaves/cell1/hmi"));
    }

    #[test]
    fn off_unless_enabled() {
        assert_eq!(resolve(&SecurityEnv::default(), None), Ok(Security::Off));
        assert_eq!(resolve(&env("false", "Enforce", None, None), Some("/nowhere")), Ok(Security::Off));
        // an invalid enclave name stops init even with security off, as in rcl
        let err = resolve(&SecurityEnv::default(), Some("tracer")).unwrap_err();
        assert_eq!(err.enclave, "tracer");
        assert!(err.to_string().starts_with("SECURITY ERROR: enclave 'tracer': not a valid enclave name"), "{err}");
    }

    #[test]
    fn finds_enclaves() {
        let ks = keystore("find");
        let got = resolve(&env("true", "Enforce", Some(&ks), None), Some("/tracer")).unwrap();
        assert_eq!(
            got,
            Security::Enclave { name: "/tracer".into(), dir: ks.join("enclaves/tracer"), strategy: Strategy::Enforce }
        );
        let got = resolve(&env("true", "Permissive", Some(&ks), None), Some("/cell1/hmi")).unwrap();
        assert_eq!(
            got,
            Security::Enclave {
                name: "/cell1/hmi".into(),
                dir: ks.join("enclaves/cell1/hmi"),
                strategy: Strategy::Permissive
            }
        );
        // no --enclave: the root enclave
        let got = resolve(&env("true", "Enforce", Some(&ks), None), None).unwrap();
        assert!(
            matches!(got, Security::Enclave { ref name, ref dir, .. } if name == "/" && *dir == ks.join("enclaves"))
        );
        // the override wins over --enclave; an empty override is no override
        let got = resolve(&env("true", "Enforce", Some(&ks), Some("/cell1/hmi")), Some("/tracer")).unwrap();
        assert!(matches!(got, Security::Enclave { ref name, .. } if name == "/cell1/hmi"));
        let got = resolve(&env("true", "Enforce", Some(&ks), Some("")), Some("/tracer")).unwrap();
        assert!(matches!(got, Security::Enclave { ref name, .. } if name == "/tracer"));
        std::fs::remove_dir_all(&ks).unwrap();
    }

    #[test]
    fn enforce_refuses_and_permissive_warns() {
        let ks = keystore("missing");
        std::fs::remove_file(ks.join("enclaves/cell1/hmi/permissions.p7s")).unwrap();
        let cases: [(Option<&Path>, Option<&str>, &str, &str); 4] = [
            (None, Some("/tracer"), "/tracer", "ROS_SECURITY_KEYSTORE is not set"),
            (Some(&ks), Some("/planner"), "/planner", "does not exist"),
            (Some(&ks), Some("/cell1/hmi"), "/cell1/hmi", "permissions.p7s' is missing"),
            (Some(Path::new("")), None, "/", "ROS_SECURITY_KEYSTORE is not set"),
        ];
        for (keystore, arg, enclave, reason) in cases {
            let err = resolve(&env("true", "Enforce", keystore, None), arg).unwrap_err();
            assert_eq!(err.enclave, enclave);
            assert!(err.reason.contains(reason), "{err}");
            let line = err.to_string();
            assert!(!line.contains('\n') && line.contains(&format!("'{enclave}'")), "{line}");
            match resolve(&env("true", "Permissive", keystore, None), arg).unwrap() {
                Security::Unsecured { warning } => {
                    assert!(warning.contains(reason) && warning.contains(enclave), "{warning}")
                }
                other => panic!("{other:?}"),
            }
        }
        std::fs::remove_dir_all(&ks).unwrap();
    }
}
