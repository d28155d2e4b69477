"""Type hashes and type descriptions (REP-2016) of tracer_calib_node, seen by a stock rclpy
node:

- endpoint_hashes: every endpoint of the node (its topics, /calibrate, the parameter
  services, ~/get_type_description, /rosout, /parameter_events, /clock, ros_discovery_info,
  and, the node being managed, the lifecycle services and ~/transition_event, and the
  bond's publisher and subscription)
  announces a RIHS01 hash that rclpy reads, equal to the one rosidl generated for its type
  (the `.json` of the wheels and of the colcon build of msg/); a service's request and
  reply topics carry the request's and the response's hash, as rmw_fastrtps and
  rmw_cyclonedds announce them;
- get_type_description: `~/get_type_description` answers for tracer_calib_msgs/msg/RawScan
  (with its sources, the `.msg` texts), and its answers (descriptions, sources, refusals of
  an unknown type or a bad hash) equal those of the stock rclpy peer's own service for the
  same requests.

Run by tests/interop/run.sh (names `type_hash`, `type_hash_<test>`) inside a private
network namespace, with the helpers of harness.py, with pytest (conftest.py).
"""

import os
import sys


sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness as t  # noqa: E402

NODE = "tracer_calibrator"


def ros_type(dds_type):
    """`pkg::msg::dds_::Name_` -> `pkg/msg/Name`."""
    package, kind, _, name = dds_type.split("::")
    return f"{package}/{kind}/{name.removesuffix('_')}"


def node_endpoints(peer, prefix):
    """Every endpoint of the participant with GUID prefix `prefix`, as rclpy sees them:
    (DDS topic, pub/sub, DDS type, hash as rclpy prints it)."""
    out = []
    for topic, _ in peer.node.get_topic_names_and_types(no_demangle=True):
        for kind, infos in (
            ("pub", peer.node.get_publishers_info_by_topic(topic, no_mangle=True)),
            ("sub", peer.node.get_subscriptions_info_by_topic(topic, no_mangle=True)),
        ):
            for i in infos:
                if bytes(i.endpoint_gid)[:12] == prefix:
                    out.append((topic, kind, i.topic_type, str(i.topic_type_hash)))
    return sorted(out)


# The endpoints the node must have (DDS topic, pub/sub), whatever else it has.
EXPECTED = [
    ("rt/raw_scan", "sub"),
    ("rt/contour", "pub"),
    ("rt/contour_polygon", "pub"),
    ("rt/calibration", "pub"),
    ("rt/diagnostics", "pub"),
    ("rt/rosout", "pub"),
    ("rt/parameter_events", "pub"),
    ("rq/calibrateRequest", "sub"),
    ("rr/calibrateReply", "pub"),
    ("ros_discovery_info", "pub"),
    ("ros_discovery_info", "sub"),
    ("rq/tracer_calibrator/get_type_descriptionRequest", "sub"),
    ("rr/tracer_calibrator/get_type_descriptionReply", "pub"),
] + [
    (f"{d}/{NODE}/{s}{suffix}", kind)
    for s in (
        "get_parameters",
        "get_parameter_types",
        "set_parameters",
        "set_parameters_atomically",
        "list_parameters",
        "describe_parameters",
    )
    for d, suffix, kind in (("rq", "Request", "sub"), ("rr", "Reply", "pub"))
]
# A managed node's (the node runs with -p managed:=true here).
EXPECTED += [(f"rt/{NODE}/transition_event", "pub")] + [
    (f"{d}/{NODE}/{s}{suffix}", kind)
    for s in ("change_state", "get_state", "get_available_states", "get_available_transitions", "get_transition_graph")
    for d, suffix, kind in (("rq", "Request", "sub"), ("rr", "Reply", "pub"))
] + [("rt/bond", "pub"), ("rt/bond", "sub")]  # nav2's bond (bond/msg/Status), kept while active


def test_endpoint_hashes(peer):
    node = t.NodeProcess("type_hash_endpoints", ["-p", "managed:=true"])
    try:
        contour = []

        def found():
            contour[:] = [i for i in peer.node.get_publishers_info_by_topic("/contour") if i.node_name == NODE]
            return bool(contour)

        peer.spin_until(found, 20, "the node's /contour publisher")
        prefix = bytes(contour[0].endpoint_gid)[:12]
        endpoints = []

        def complete():
            endpoints[:] = node_endpoints(peer, prefix)
            have = {(topic, kind) for topic, kind, _, _ in endpoints}
            return all(e in have for e in EXPECTED)

        peer.spin_until(complete, 20, lambda: f"all endpoints; have {endpoints}")
        for topic, kind, dds_type, hash_string in endpoints:
            expected = t.rosidl_hash(ros_type(dds_type))
            assert hash_string == expected, f"{topic} ({kind}, {dds_type}): {hash_string}, rosidl: {expected}"
        return f"{len(endpoints)} endpoints, every hash rosidl's"
    finally:
        node.stop()


def fields(response):
    """A GetTypeDescription response as plain data, to compare two."""
    def individual(d):
        return (d.type_name, [(f.name, f.type.type_id, f.type.capacity, f.type.string_capacity,
                               f.type.nested_type_name, f.default_value) for f in d.fields])

    td = response.type_description
    return (
        response.successful,
        response.failure_reason,
        individual(td.type_description),
        [individual(d) for d in td.referenced_type_descriptions],
        [(s.type_name, s.encoding, s.raw_file_contents) for s in response.type_sources],
    )


# The standard texts the node carries (Kilted's).
STANDARD = os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../src/interfaces/standard")


def same_texts(mine, stock):
    """The two answers, each source the peer's distribution ships with a text other than
    ours left out of both (Jazzy's builtin_interfaces/msg/Time has a longer comment than
    Kilted's, which the node carries; the hash is the same)."""
    def differs(type_name):
        package, kind, name = type_name.split("/")
        path = os.path.join(STANDARD, kind, package, name + "." + kind)
        return os.path.exists(path) and open(path).read().rstrip("\n") != dict(
            (s[0], s[2]) for s in stock[4]
        ).get(type_name, open(path).read().rstrip("\n"))

    keep = lambda answer: (*answer[:4], [s for s in answer[4] if not differs(s[0])])  # noqa: E731
    return keep(mine), keep(stock)


def test_get_type_description(peer):
    """RawScan with and without sources; the answers equal a stock rclpy node's own for the
    same types (RawScan, which the peer publishes too; rcl_interfaces/msg/Log; the
    GetTypeDescription service); an empty, a malformed and an unknown hash refused with
    rcl's reasons."""
    from type_description_interfaces.srv import GetTypeDescription
    from tracer_calib_msgs.msg import RawScan

    node = t.NodeProcess("type_hash_describe", [])
    try:
        peer.node.create_publisher(RawScan, "type_hash_scans", 1)  # so that rclpy describes it too
        ours = peer.node.create_client(GetTypeDescription, f"/{NODE}/get_type_description")
        theirs = peer.node.create_client(GetTypeDescription, f"/{peer.node.get_name()}/get_type_description")
        peer.spin_until(lambda: ours.service_is_ready() and theirs.service_is_ready(), 20, "~/get_type_description")

        def call(client, type_name, type_hash, sources):
            request = GetTypeDescription.Request(
                type_name=type_name, type_hash=type_hash, include_type_sources=sources
            )
            return peer.retry(lambda: client.call_async(request), f"the description of {type_name}")

        raw_scan = "tracer_calib_msgs/msg/RawScan"
        r = call(ours, raw_scan, t.rosidl_hash(raw_scan), True)
        assert r.successful, r.failure_reason
        assert r.type_description.type_description.type_name == raw_scan
        referenced = [d.type_name for d in r.type_description.referenced_type_descriptions]
        assert referenced == ["builtin_interfaces/msg/Time", "std_msgs/msg/Header"], referenced
        sources = {s.type_name: s for s in r.type_sources}
        assert list(sources) == [raw_scan, *referenced], list(sources)
        assert all(s.encoding == "msg" for s in sources.values())
        share = next(
            p
            for p in os.environ["AMENT_PREFIX_PATH"].split(":")
            if os.path.isdir(os.path.join(p, "share", "tracer_calib_msgs"))
        )
        with open(os.path.join(share, "share/tracer_calib_msgs/msg/RawScan.msg")) as f:
            assert sources[raw_scan].raw_file_contents == f.read().rstrip("\n")
        compared = 0
        for type_name in (raw_scan, "rcl_interfaces/msg/Log", "type_description_interfaces/srv/GetTypeDescription"):
            for with_sources in (True, False):
                mine = fields(call(ours, type_name, t.rosidl_hash(type_name), with_sources))
                stock = fields(call(theirs, type_name, t.rosidl_hash(type_name), with_sources))
                mine, stock = same_texts(mine, stock)
                assert mine == stock, f"{type_name}, sources {with_sources}:\n ours {mine}\n rclpy {stock}"
                compared += 1
        # Refusals, with rcl's reasons.
        for type_name, type_hash in (
            (raw_scan, ""),
            (raw_scan, "RIHS01_12"),
            ("sensor_msgs/msg/Image", "RIHS01_" + "0" * 64),
            ("std_msgs/msg/Header", t.rosidl_hash("std_msgs/msg/Header")),
        ):
            mine = fields(call(ours, type_name, type_hash, False))
            stock = fields(call(theirs, type_name, type_hash, False))
            assert not mine[0] and mine[1], mine
            assert mine == stock, f"{type_name} {type_hash!r}: ours {mine}, rclpy {stock}"
            compared += 1
        return f"{compared} answers equal rclpy's own"
    finally:
        node.stop()
