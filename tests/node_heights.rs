//! `tracer_calib_node` (the binary, over DDS on loopback) and the height channel: a frame
//! scan with `height_counts` comes back with its 3-D length and frame curve, and the same
//! scan as a driver built before `height_counts` was appended sends it (the message ends
//! after `counts`) is corrected as one without heights, not dropped.
//!
//! Run inside a private network namespace, as `scripts/test.sh` runs `cargo test`.

use std::net::{IpAddr, Ipv4Addr};
use std::process::Command;

use futures::StreamExt;
use nalgebra::Vector2;
use rand::SeedableRng;
use ros2_client::dds::Context;
use ros2_client::{Name, NodeName, NodeOptions};
use rustdds::{DomainParticipantBuilder, QosPolicies, TopicKind};
use tracer_calib::engine::geometry::Mounting;
use tracer_calib::engine::shape::RoundedRect;
use tracer_calib::engine::simulate::{HeightOptions, SimOptions, on_sphere, simulate, simulate_heights};
use tracer_calib::interfaces::{Contour, Header, RawScan, RosMsg, to_cdr};

mod common;
use common::{NodeProcess, Raw, RawAdapter, reliable, within};

const DOMAIN: u16 = 97;

#[test]
fn heights_over_dds_and_a_driver_without_them() {
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
        .new_node(NodeName::new("/", "node_heights_test").unwrap(), NodeOptions::new().enable_rosout(false))
        .unwrap();
    let raw_t = peer
        .create_topic(&Name::new("/", "raw_scan").unwrap(), RawScan::NAME.message_type_name(), &reliable(10))
        .unwrap();
    let contour_t = peer
        .create_topic(&Name::new("/", "contour").unwrap(), Contour::NAME.message_type_name(), &reliable(10))
        .unwrap();
    let publisher = peer.create_publisher::<RawScan>(&raw_t, None).unwrap();
    let contours = peer.create_subscription::<Contour>(&contour_t, None).unwrap();
    // A driver of the earlier RawScan: its payloads, raw, on the same topic.
    let dp = ctx.domain_participant();
    let qos: QosPolicies = (&reliable(10)).into();
    let topic = dp.create_topic("rt/raw_scan".into(), RawScan::NAME.dds_type_name(), &qos, TopicKind::NoKey).unwrap();
    let earlier = dp.create_publisher(&qos).unwrap().create_datawriter_no_key::<Raw, RawAdapter>(&topic, None).unwrap();
    let spinner = smol::spawn(peer.spinner().unwrap().spin());

    // A 52 x 32 mm frame on a base-6 sphere, traced by an ideally mounted tracer (the node
    // has no calibration: it corrects with the ideal mounting, no tilt).
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let frame = RoundedRect { center: Vector2::new(0.0005, -0.0003), half_w: 0.026, half_h: 0.016, radius: 0.005 };
    let opt = SimOptions { noise: 1e-6, quantum: 1e-6, inside: true, ..SimOptions::default() };
    let sim = simulate(&frame, &Mounting::IDEAL, &opt, &mut rng).unwrap();
    let heights = HeightOptions { zero: 0.0, tilt: [0.0; 2], noise: 1e-6, quantum: 1e-6 };
    let z = simulate_heights(&sim, on_sphere(6.0, frame.center, 0.002), &heights, &mut rng).unwrap();
    let msg = |scan_id: u32, with_heights: bool| RawScan {
        header: Header::default(),
        scan_id,
        target: RawScan::TARGET_FRAME,
        steps_per_revolution: 400,
        step: sim.scan.samples().iter().map(|s| s.step).collect(),
        counts: sim.scan.samples().iter().map(|s| (s.rho / 1e-6).round() as i32).collect(),
        height_counts: if with_heights { z.iter().map(|h| (h / 1e-6).round() as i32).collect() } else { Vec::new() },
    };

    smol::block_on(async {
        let mut stream = std::pin::pin!(contours.async_stream());
        // Publish until the contour of `scan_id` comes back (the first may go out before
        // the node's subscription matched).
        let mut exchange = async |scan_id: u32, send: &dyn Fn()| -> Contour {
            for _ in 0..20 {
                send();
                let wait = async {
                    while let Some(Ok((c, _))) = stream.next().await {
                        if c.scan_id == scan_id {
                            return c;
                        }
                    }
                    panic!("the contour stream ended")
                };
                if let Ok(c) = smol::future::or(async { Ok(wait.await) }, async {
                    smol::Timer::after(std::time::Duration::from_secs(1)).await;
                    Err(())
                })
                .await
                {
                    return c;
                }
            }
            panic!("no contour for scan {scan_id}")
        };
        let with = within(40, "the contour of a scan with heights", async {
            exchange(1, &|| publisher.publish(msg(1, true)).unwrap()).await
        })
        .await;
        assert!(with.circumference > 0.15, "{}", with.circumference);
        let excess = with.circumference_3d - with.circumference;
        assert!(excess > 0.5e-3 && excess < 2e-3, "3-D adds {excess} m");
        assert!(with.circumference_3d_u95 > 0.0);
        assert!((with.frame_curve - 6.0).abs() < 0.1, "{}", with.frame_curve);
        assert!(with.points.iter().all(|p| p.z > 0.002 && p.z < 0.008), "{:?}", &with.points[..3]);

        // The same scan from a driver built before height_counts: the payload ends after counts.
        let m = msg(2, false);
        let payload = to_cdr(&(m.header, m.scan_id, m.target, m.steps_per_revolution, m.step, m.counts)).unwrap();
        let without = within(40, "the contour of a scan from an earlier driver", async {
            exchange(2, &|| earlier.write(Raw(payload[4..].to_vec()), None).unwrap()).await
        })
        .await;
        assert_eq!(without.circumference, with.circumference);
        assert_eq!(without.circumference_3d, without.circumference);
        assert_eq!(without.frame_curve, 0.0);
        assert!(without.points.iter().all(|p| p.z == 0.0));
    });
    drop(spinner);
}
