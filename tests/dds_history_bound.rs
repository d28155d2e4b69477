//! The DDS layer holds what the QoS depths allow, whatever is published through it
//! (`vendor/rustdds/PATCHES.md`, "A KEEP_LAST writer releases samples").
//!
//! Two rustdds participants in this process (localhost only, domain 93; `scripts/test.sh`
//! runs the tests inside a private network namespace): a reliable KEEP_LAST 10 writer,
//! as the node's `contour`, and a reliable KEEP_LAST 100 reader, as its `raw_scan`, of
//! 16 kB samples. 2000 samples go through in rounds of 100; the reader takes every one.
//! Checked from the caches' own counts, not from time or RSS:
//! - at every write, the writer holds at most its depth plus the samples written since
//!   the last round was acknowledged (published rustdds: every sample of the last 6 s);
//! - once a round is acknowledged, the writer holds at most its depth;
//! - the reader's topic cache never holds more than its depth (or rustdds' default
//!   resource limit, 64, if larger) plus the 8 samples between two of its collections;
//! - every sample arrives, in order.

use std::net::{IpAddr, Ipv4Addr};
use std::time::{Duration, Instant};

use rustdds::no_key::{DataWriter, SimpleDataReader};
use rustdds::policy::{Durability, History, Reliability};
use rustdds::serialization::{CDRDeserializerAdapter, CDRSerializerAdapter};
use rustdds::{DomainParticipant, DomainParticipantBuilder, QosPolicies, QosPolicyBuilder, TopicKind};
use serde::{Deserialize, Serialize};

const DOMAIN: u16 = 93;
const WRITER_DEPTH: usize = 10;
const READER_DEPTH: usize = 100;
const SAMPLES: u32 = 2000;
const ROUND: u32 = 100;
const PAYLOAD: usize = 16 * 1024;

#[derive(Serialize, Deserialize, Clone, Debug)]
struct Blob {
    seq: u32,
    data: Vec<u8>,
}

fn qos(depth: usize) -> QosPolicies {
    QosPolicyBuilder::new()
        .reliability(Reliability::Reliable { max_blocking_time: rustdds::Duration::from_secs(5) })
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: depth as i32 })
        .build()
}

fn participant() -> DomainParticipant {
    DomainParticipantBuilder::new(DOMAIN)
        .with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)])
        .build()
        .expect("participant")
}

type Reader = SimpleDataReader<Blob, CDRDeserializerAdapter<Blob>>;

/// Takes samples until one with `seq >= until` has come, or the deadline passes.
/// Returns the seq numbers taken.
fn take_until(reader: &Reader, until: u32, deadline: Instant, max_cached: &mut usize) -> Vec<u32> {
    let mut got = Vec::new();
    loop {
        reader.drain_read_notifications();
        while let Some(s) = reader.try_take_one().expect("take") {
            *max_cached = (*max_cached).max(reader.topic_cache_sample_count());
            got.push(s.into_value().seq);
        }
        if got.last().is_some_and(|&s| s >= until) || Instant::now() > deadline {
            return got;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
}

#[test]
fn writer_and_reader_caches_stay_within_their_depths() {
    let (pw, pr) = (participant(), participant());
    let tw = pw.create_topic("history_bound".into(), "Blob".into(), &qos(WRITER_DEPTH), TopicKind::NoKey).unwrap();
    let tr = pr.create_topic("history_bound".into(), "Blob".into(), &qos(READER_DEPTH), TopicKind::NoKey).unwrap();
    let writer: DataWriter<Blob, CDRSerializerAdapter<Blob>> = pw
        .create_publisher(&qos(WRITER_DEPTH))
        .unwrap()
        .create_datawriter_no_key(&tw, Some(qos(WRITER_DEPTH)))
        .unwrap();
    let reader: Reader = pr
        .create_subscriber(&qos(READER_DEPTH))
        .unwrap()
        .create_simple_datareader_no_key(&tr, Some(qos(READER_DEPTH)))
        .unwrap();

    // Discovery: probes (seq 0) until one arrives.
    let mut max_cached = 0;
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        writer.write(Blob { seq: 0, data: vec![] }, None).unwrap();
        if !take_until(&reader, 0, Instant::now() + Duration::from_millis(200), &mut max_cached).is_empty() {
            break;
        }
        assert!(Instant::now() < deadline, "the reader never matched the writer");
    }
    assert!(writer.wait_for_acknowledgments(Duration::from_secs(10)).unwrap(), "probes not acknowledged");

    let data = vec![0x5a; PAYLOAD];
    let (mut received, mut max_held) = (Vec::new(), 0);
    for round in 0..SAMPLES / ROUND {
        let first = round * ROUND + 1;
        for seq in first..first + ROUND {
            writer.write(Blob { seq, data: data.clone() }, None).unwrap();
            let held = writer.history_sample_count();
            max_held = max_held.max(held);
            assert!(
                held <= WRITER_DEPTH + ROUND as usize,
                "writer holds {held} samples at seq {seq}: more than its depth {WRITER_DEPTH} + the {ROUND} \
                 written since the last acknowledged round"
            );
        }
        let last = first + ROUND - 1;
        let got = take_until(&reader, last, Instant::now() + Duration::from_secs(30), &mut max_cached);
        received.extend(got.into_iter().filter(|&s| s > 0));
        assert_eq!(received.last(), Some(&last), "round {round}: not everything arrived");
        assert!(writer.wait_for_acknowledgments(Duration::from_secs(10)).unwrap(), "round {round} not acknowledged");
        let held = writer.history_sample_count();
        assert!(held <= WRITER_DEPTH, "round {round} acknowledged, yet the writer holds {held} > {WRITER_DEPTH}");
    }
    assert_eq!(received, (1..=SAMPLES).collect::<Vec<_>>(), "every sample, once, in order");
    let reader_bound = READER_DEPTH.max(64) + 8;
    assert!(max_cached <= reader_bound, "reader's topic cache held {max_cached} > {reader_bound}");
    println!(
        "{SAMPLES} samples of {PAYLOAD} B: writer held at most {max_held} (depth {WRITER_DEPTH}), \
         reader's cache at most {max_cached} (depth {READER_DEPTH})"
    );
}
