//! A DataWriter's and a DataReader's USER_DATA QoS policy reaches other participants in
//! their SEDP data (`vendor/rustdds/PATCHES.md`, "USER_DATA").
//!
//! Two rustdds participants in this process (localhost only, domain 94; `scripts/test.sh`
//! runs the tests inside a private network namespace). The first makes a writer and a
//! reader with USER_DATA (a ROS 2 type hash, 81 bytes: not a multiple of 4, so the
//! parameter is padded) and a writer without; the second sees each through discovery
//! (`WriterDetected` / `ReaderDetected`), so what it reports has been serialized by one
//! participant and parsed by the other: the octets exactly, and none for the writer
//! without. Published rustdds 0.15.1 sends no USER_DATA at all (and kept the raw
//! parameter value, length prefix and padding included, of a remote one).

use std::collections::HashMap;
use std::net::{IpAddr, Ipv4Addr};
use std::time::{Duration, Instant};

use rustdds::dds::qos::HasQoSPolicy;
use rustdds::no_key::{DataReader, DataWriter};
use rustdds::policy::{Reliability, UserData};
use rustdds::serialization::{CDRDeserializerAdapter, CDRSerializerAdapter};
use rustdds::{
    DomainParticipant, DomainParticipantBuilder, DomainParticipantStatusEvent, GUID, QosPolicies, QosPolicyBuilder,
    RTPSEntity, StatusEvented, TopicKind,
};

const DOMAIN: u16 = 94;
const WRITER_DATA: &str = "typehash=RIHS01_339b7ad09e0bb6a3760754fd4ef1c7f923d3266b82156de573ba403eddab0dc2;";

fn participant() -> DomainParticipant {
    DomainParticipantBuilder::new(DOMAIN)
        .with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)])
        .build()
        .expect("participant")
}

fn qos() -> QosPolicies {
    QosPolicyBuilder::new()
        .reliability(Reliability::Reliable { max_blocking_time: rustdds::Duration::from_secs(1) })
        .build()
}

fn with(user_data: &[u8]) -> QosPolicies {
    qos().with_user_data(UserData { value: user_data.to_vec() })
}

#[test]
fn user_data_goes_out_in_sedp_and_comes_back_as_its_octets() {
    let (ours, theirs) = (participant(), participant());
    let topic = ours.create_topic("user_data".into(), "Blob".into(), &qos(), TopicKind::NoKey).unwrap();
    let publisher = ours.create_publisher(&qos()).unwrap();
    let subscriber = ours.create_subscriber(&qos()).unwrap();
    let reader_data: &[u8] = b"\x00\x01 any octets \xff";
    let with_data: DataWriter<u32, CDRSerializerAdapter<u32>> =
        publisher.create_datawriter_no_key(&topic, Some(with(WRITER_DATA.as_bytes()))).unwrap();
    let without: DataWriter<u32, CDRSerializerAdapter<u32>> = publisher.create_datawriter_no_key(&topic, None).unwrap();
    let reader: DataReader<u32, CDRDeserializerAdapter<u32>> =
        subscriber.create_datareader_no_key(&topic, Some(with(reader_data))).unwrap();
    assert_eq!(with_data.qos().user_data().map(|u| u.value), Some(WRITER_DATA.as_bytes().to_vec()));

    let expected: HashMap<GUID, Vec<u8>> = [
        (with_data.guid(), WRITER_DATA.as_bytes().to_vec()),
        (without.guid(), Vec::new()),
        (reader.guid(), reader_data.to_vec()),
    ]
    .into();
    let listener = theirs.status_listener();
    let mut seen: HashMap<GUID, Vec<u8>> = HashMap::new();
    let deadline = Instant::now() + Duration::from_secs(20);
    while expected.keys().any(|g| !seen.contains_key(g)) && Instant::now() < deadline {
        match listener.try_recv_status() {
            Some(DomainParticipantStatusEvent::WriterDetected { writer: e })
            | Some(DomainParticipantStatusEvent::ReaderDetected { reader: e }) => {
                seen.insert(e.guid, e.user_data);
            }
            Some(_) => {}
            None => std::thread::sleep(Duration::from_millis(10)),
        }
    }
    for (guid, user_data) in &expected {
        assert_eq!(seen.get(guid), Some(user_data), "{guid:?}: seen {seen:?}");
    }
}
