//! What the integration tests that run a node share: a deadline on a future, the node
//! process (killed when dropped), the ROS default reliable QoS, a `/diagnostics` value.
#![allow(dead_code)] // each test uses some of it

use std::process::Child;
use std::time::Duration;

use futures::{FutureExt, future};
use ros2_client::{QosProfile, qos::*};
use tracer_calib::interfaces::DiagnosticArray;

#[cfg(feature = "zenoh")]
pub mod on_zenoh;

/// `f`, or a panic naming `what` after `secs` seconds.
pub async fn within<T>(secs: u64, what: &str, f: impl std::future::Future<Output = T>) -> T {
    let timeout = FutureExt::map(smol::Timer::after(Duration::from_secs(secs)), |_| None);
    match future::select(Box::pin(f.map(Some)), Box::pin(timeout)).await.factor_first().0 {
        Some(v) => v,
        None => panic!("timed out after {secs} s: {what}"),
    }
}

/// A node process, killed when dropped.
pub struct NodeProcess(pub Child);
impl Drop for NodeProcess {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Reliable, volatile, keep last `depth`.
pub fn reliable(depth: usize) -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth })
}

/// The value of `key` in the node's diagnostics.
pub fn value(d: &DiagnosticArray, key: &str) -> Option<String> {
    d.status.first()?.values.iter().find(|kv| kv.key == key).map(|kv| kv.value.clone())
}

/// Raw bytes as a DDS sample's payload, CDR little-endian: what a writer of no known
/// layout sends.
#[derive(Debug)]
pub struct Raw(pub Vec<u8>);
pub struct RawAdapter;
impl rustdds::no_key::SerializerAdapter<Raw> for RawAdapter {
    type Error = std::io::Error;
    fn output_encoding() -> rustdds::RepresentationIdentifier {
        rustdds::RepresentationIdentifier::CDR_LE
    }
    fn to_bytes(value: &Raw) -> Result<rustdds::bytes::Bytes, Self::Error> {
        Ok(rustdds::bytes::Bytes::from(value.0.clone()))
    }
}
