//! `tracer_calib_node` (the binary, over DDS on loopback) given `calibrate` requests that fit
//! no client layout: none is answered, each is counted on `/diagnostics`
//! (`requests_unreadable`), and the node goes on answering good requests.
//!
//! Run inside a private network namespace, as `scripts/test.sh` runs `cargo test`.

use std::net::{IpAddr, Ipv4Addr};
use std::process::Command;
use std::time::{Duration, Instant};

use futures::StreamExt;
use ros2_client::dds::{Context, ServiceMapping};
use ros2_client::{Name, NodeName, NodeOptions};
use rustdds::{DomainParticipantBuilder, QosPolicies, TopicKind};
use tracer_calib::interfaces::{Calibrate, CalibrateRequest, CalibrateResponse, DiagnosticArray, RosMsg, RosService};

mod common;
use common::{NodeProcess, Raw, RawAdapter, reliable, value, within};

const DOMAIN: u16 = 96;

#[test]
fn unreadable_requests_are_counted_on_diagnostics_and_the_node_keeps_serving() {
    let _node = NodeProcess(
        Command::new(env!("CARGO_BIN_EXE_tracer_calib_node"))
            .env("ROS_DOMAIN_ID", DOMAIN.to_string())
            .env("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
            .spawn()
            .expect("the node starts"),
    );
    let participant = DomainParticipantBuilder::new(DOMAIN)
        .with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)])
        .build()
        .expect("participant");
    let ctx = Context::from_domain_participant(participant).expect("context");
    let mut peer = ctx
        .new_node(NodeName::new("/", "unreadable_requests_test").unwrap(), NodeOptions::new().enable_rosout(false))
        .unwrap();
    let client = peer
        .create_client::<CalibrateRequest, CalibrateResponse>(
            ServiceMapping::Enhanced,
            &Name::new("/", "calibrate").unwrap(),
            &Calibrate::type_name(),
            reliable(100),
            reliable(100),
        )
        .unwrap();
    let diag_topic = peer
        .create_topic(&Name::new("/", "diagnostics").unwrap(), DiagnosticArray::NAME.message_type_name(), &reliable(10))
        .unwrap();
    let diagnostics = peer.create_subscription::<DiagnosticArray>(&diag_topic, None).unwrap();
    // A writer of raw payloads on the calibrate request topic.
    let dp = ctx.domain_participant();
    let request_qos: QosPolicies = (&reliable(100)).into();
    let topic = dp
        .create_topic(
            "rq/calibrateRequest".into(),
            <Calibrate as RosService>::Request::NAME.dds_type_name(),
            &request_qos,
            TopicKind::NoKey,
        )
        .unwrap();
    let raw =
        dp.create_publisher(&request_qos).unwrap().create_datawriter_no_key::<Raw, RawAdapter>(&topic, None).unwrap();
    let spinner = smol::spawn(peer.spinner().unwrap().spin());

    smol::block_on(async {
        within(30, "the node's calibrate service", client.wait_for_service(&peer)).await;
        let first = within(10, "a first call", client.async_call_service(CalibrateRequest::default())).await.unwrap();
        assert!(first.message.starts_with("no calibration-plate scan received yet"), "{}", first.message);

        // Three payloads of no client layout: a bool of 9 (Enhanced and Cyclone alike),
        // too short, and a request with 8 bytes too many.
        for bad in [vec![9u8; 24], vec![1, 2, 3], vec![1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 7, 7, 7, 7]] {
            raw.write(Raw(bad), None).unwrap();
        }
        let mut stream = std::pin::pin!(diagnostics.async_stream());
        let deadline = Instant::now() + Duration::from_secs(15);
        let counted = within(20, "requests_unreadable 3 on /diagnostics", async {
            while let Some(Ok((d, _))) = stream.next().await {
                if value(&d, "requests_unreadable").as_deref() == Some("3") || Instant::now() > deadline {
                    return value(&d, "requests_unreadable");
                }
            }
            None
        })
        .await;
        assert_eq!(counted.as_deref(), Some("3"));

        // And the node answers the next good request.
        let again = within(10, "a call after the bad ones", client.async_call_service(CalibrateRequest::default()))
            .await
            .unwrap();
        assert!(!again.success && again.message.starts_with("no calibration-plate scan"), "{}", again.message);
    });
    drop(spinner);
}
