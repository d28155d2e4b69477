//! A ros2-client service server reads each request in the layout its client used and
//! answers in that layout (`vendor/ros2-client/PATCHES.md`, "Each service
//! request is read, and answered, in its client's layout").
//!
//! Real DDS between two rustdds participants in this process (localhost only, domain
//! 94; `scripts/test.sh` runs the tests inside a private network namespace): one server,
//! made with the Enhanced mapping as the node's `/calibrate` is, and two clients of
//! another node calling it at the same time, one in the Enhanced layout (the request
//! is the payload) and one in the Cyclone layout (a 16-byte header, client id and
//! sequence number, before the request). Both writers have rustdds' vendor id, so the
//! server decides by the payload's shape here; the vendor ids of Fast DDS and Cyclone
//! DDS are exercised by the interop tests with the stock peers (tests/interop/
//! test_cyclone.py). Then a raw writer sends payloads that fit neither layout: each is
//! an error the server counts, nothing is answered, and the clients are served on.

use std::net::{IpAddr, Ipv4Addr};
use std::time::Duration;

use futures::{FutureExt, StreamExt, future};
use ros2_client::dds::{Context, ServiceMapping};
use ros2_client::{Message, Name, NodeName, NodeOptions, QosProfile, ServiceTypeName, qos::*};
use rustdds::{DomainParticipantBuilder, QosPolicies, TopicKind};
use serde::{Deserialize, Serialize};

mod common;
use common::{Raw, RawAdapter, within};

const DOMAIN: u16 = 94;
const CALLS: u32 = 25;

/// The shape of tracer_calib_msgs/srv/Calibrate's request, whose misreading showed the bug
/// (a Cyclone request read as Enhanced: "Expected 0 or 1 as Boolean, got: 9").
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
struct Request {
    scan_id: u32,
    dry_run: bool,
}
impl Message for Request {}

#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
struct Response {
    scan_id: u32,
    message: String,
}
impl Message for Response {}

fn qos() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 1000 })
}

fn context() -> Context {
    let participant = DomainParticipantBuilder::new(DOMAIN)
        .with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)])
        .build()
        .expect("participant");
    Context::from_domain_participant(participant).expect("context")
}

fn service_name() -> Name {
    Name::new("/", "layout_test").unwrap()
}

fn type_name() -> ServiceTypeName {
    ServiceTypeName::new("tracer_calib_test", "Layouts")
}

/// `CALLS` calls, one after the other, with scan ids `first`, `first + 2`, ...
async fn calls(client: &ros2_client::dds::Client<Request, Response>, first: u32) -> Vec<(Request, Response)> {
    let mut out = Vec::new();
    for i in 0..CALLS {
        let r = Request { scan_id: first + 2 * i, dry_run: i % 2 == 0 };
        let resp = client.async_call_service(r.clone()).await;
        out.push((r.clone(), resp.unwrap_or_else(|e| panic!("call {r:?} failed: {e:?}"))));
    }
    out
}

#[test]
fn one_server_answers_each_client_in_its_own_layout() {
    let _ = env_logger::builder().is_test(true).try_init();
    let server_ctx = context();
    let mut server_node = server_ctx
        .new_node(NodeName::new("/", "layout_server").unwrap(), NodeOptions::new().enable_rosout(false))
        .unwrap();
    let server = server_node
        .create_server::<Request, Response>(ServiceMapping::Enhanced, &service_name(), &type_name(), qos(), qos())
        .unwrap();
    let server_spinner = smol::spawn(server_node.spinner().unwrap().spin());

    let client_ctx = context();
    let mut client_node = client_ctx
        .new_node(NodeName::new("/", "layout_clients").unwrap(), NodeOptions::new().enable_rosout(false))
        .unwrap();
    let enhanced = client_node
        .create_client::<Request, Response>(ServiceMapping::Enhanced, &service_name(), &type_name(), qos(), qos())
        .unwrap();
    let cyclone = client_node
        .create_client::<Request, Response>(ServiceMapping::Cyclone, &service_name(), &type_name(), qos(), qos())
        .unwrap();
    // A writer of raw payloads on the request topic.
    let dp = client_ctx.domain_participant();
    let request_qos: QosPolicies = (&qos()).into();
    let raw_topic = dp
        .create_topic(
            "rq/layout_testRequest".into(),
            "tracer_calib_test::srv::dds_::Layouts_Request_".into(),
            &request_qos,
            TopicKind::NoKey,
        )
        .unwrap();
    let raw = dp
        .create_publisher(&request_qos)
        .unwrap()
        .create_datawriter_no_key::<Raw, RawAdapter>(&raw_topic, None)
        .unwrap();
    let client_spinner = smol::spawn(client_node.spinner().unwrap().spin());

    smol::block_on(async {
        // The server: every request answered with its own scan_id; unreadable ones counted.
        let serve = async {
            let mut requests = std::pin::pin!(server.receive_request_stream());
            let mut errors = 0u64;
            while let Some(item) = requests.next().await {
                match item {
                    Ok((id, req)) => {
                        let message = format!("scan {} dry_run {}", req.scan_id, req.dry_run);
                        server.async_send_response(id, Response { scan_id: req.scan_id, message }).await.unwrap();
                    }
                    Err(_) => errors += 1,
                }
                assert_eq!(errors, server.bad_request_count(), "every unreadable request is counted");
            }
        };
        let calls = async {
            within(10, "service matched", async {
                enhanced.wait_for_service(&client_node).await;
                cyclone.wait_for_service(&client_node).await;
            })
            .await;
            // Both clients at once, each call its own answer. (One ros2-client Client
            // makes one call at a time: concurrent calls on it take each other's
            // responses from its one reader.)
            let round = |base: u32| {
                future::join(calls(&enhanced, base), calls(&cyclone, base + 1)).map(|(mut a, b)| {
                    a.extend(b);
                    a
                })
            };
            for (req, resp) in within(20, "the first round of calls", round(1000)).await {
                assert_eq!(resp.scan_id, req.scan_id);
                assert_eq!(resp.message, format!("scan {} dry_run {}", req.scan_id, req.dry_run));
            }
            assert_eq!(server.bad_request_count(), 0);

            // Payloads that fit neither layout: each is counted, none answered.
            let bad: [&[u8]; 4] = [
                &[1, 2, 3],                                        // too short for either
                &[9; 24],                                          // a bool of 9 either way
                &[1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 7, 7, 7, 7], // a request and 8 bytes more
                &[0; 64],                                          // a Cyclone header, a request, 40 more
            ];
            for b in bad {
                raw.write(Raw(b.to_vec()), None).unwrap();
            }
            within(10, "the bad requests counted", async {
                while server.bad_request_count() < bad.len() as u64 {
                    smol::Timer::after(Duration::from_millis(10)).await;
                }
            })
            .await;
            assert_eq!(server.bad_request_count(), bad.len() as u64);

            // And the server goes on serving both layouts.
            for (req, resp) in within(20, "the second round of calls", round(5000)).await {
                assert_eq!(resp.scan_id, req.scan_id);
            }
            assert_eq!(server.bad_request_count(), bad.len() as u64);
        };
        future::select(Box::pin(serve), Box::pin(calls)).await;
    });
    drop(client_spinner);
    drop(server_spinner);
}
