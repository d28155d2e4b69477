pub mod access_control;
pub mod authentication;
mod certificate;
pub mod config;
pub mod cryptographic;
pub mod logging;
mod private_key;
pub mod security_plugins;
pub mod types;

pub use types::*;
// export top-level plugin interfaces
pub use access_control::{
  access_control_builtin::AccessControlBuiltin, access_control_plugin::AccessControl,
};
pub use authentication::{
  authentication_builtin::AuthenticationBuiltin, authentication_plugin::Authentication,
};
pub use cryptographic::{cryptographic_builtin::CryptographicBuiltin, Cryptographic};

// tracer_calib patch (security): how many remote participants failed authentication
// (their identity, or a handshake message they sent, did not validate: a certificate of
// another CA, expired, a bad signature), each counted once, in this process. Read with
// `rustdds::remote_participants_refused_authentication`.
static REFUSED_AUTHENTICATION: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

pub(crate) fn count_refused_authentication() {
  REFUSED_AUTHENTICATION.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
}

/// tracer_calib patch (security): the number of remote participants whose authentication
/// failed in this process's participants (identity or handshake refused), each once.
pub fn remote_participants_refused_authentication() -> u64 {
  REFUSED_AUTHENTICATION.load(std::sync::atomic::Ordering::Relaxed)
}
