//! ROS 2 names: node names, namespaces, topic and service names, validated, expanded and
//! remapped as rcl does.
//!
//! [`expand_name`] and [`resolve_topic`] follow `rcl_expand_topic_name` and `rcl_remap_*`:
//! an absolute name (`/x`) stays; `~` and `~/x` are private names (`/ns/node`, `/ns/node/x`);
//! `{node}`, `{ns}`, `{namespace}` are substituted; any other relative name gets the namespace
//! (`x` -> `/ns/x`). A remap rule's `FROM` is expanded the same way and compared with the
//! expanded name, so `-r raw_scan:=/x` and `-r /cell1/raw_scan:=/x` both match `raw_scan` in
//! namespace `/cell1`; the replacement is expanded too. A rule with a `NODE:` prefix applies only
//! to the node of that name: for `__node`/`__ns` rules the name the node was created with, for
//! topic rules the node's final (remapped) name, as in rcl.
//!

use std::fmt;

mod remap;
pub use remap::{RemapKind, RemapRule};

/// A name token: `[A-Za-z0-9_]+`.
pub(crate) fn is_token(s: &str) -> bool {
    !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// An invalid node name, namespace, or topic or service name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("invalid {what} '{name}': {reason}")]
pub struct NameError {
    /// What kind of name: `node name`, `namespace`, `topic or service name`...
    pub what: &'static str,
    /// The name.
    pub name: String,
    /// What is wrong with it.
    pub reason: String,
}

impl NameError {
    fn new(what: &'static str, name: &str, reason: impl Into<String>) -> Self {
        NameError { what, name: name.to_string(), reason: reason.into() }
    }
}

/// A node's final name and namespace.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct NodeIdentity {
    /// The base name, e.g. `tracer`.
    pub name: String,
    /// The absolute namespace, `/` for the root, never with a trailing `/` otherwise.
    pub namespace: String,
}

impl NodeIdentity {
    /// rcl's logger name: the namespace's tokens and the name joined by dots
    /// (`cell1.tracer`; `tracer` in the root namespace).
    pub fn logger_name(&self) -> String {
        self.namespace.split('/').filter(|t| !t.is_empty()).chain([self.name.as_str()]).collect::<Vec<_>>().join(".")
    }

    /// `/ns/name`, or `/name` in the root namespace.
    pub fn fully_qualified_name(&self) -> String {
        fully_qualified_node_name(&self.namespace, &self.name)
    }

    /// The same, as ros2-client's `NodeName` (which also rejects some names rcl accepts).
    pub fn ros2_node_name(&self) -> Result<ros2_client::NodeName, NameError> {
        ros2_client::NodeName::new(&self.namespace, &self.name)
            .map_err(|e| NameError::new("node name", &self.fully_qualified_name(), e.to_string()))
    }
}

impl fmt::Display for NodeIdentity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.fully_qualified_name())
    }
}

/// `/ns/name`, or `/name` when `namespace` is the root `/` (or empty).
pub fn fully_qualified_node_name(namespace: &str, name: &str) -> String {
    let ns = normalize_namespace(namespace);
    if ns == "/" { format!("/{name}") } else { format!("{ns}/{name}") }
}

/// Makes a namespace absolute without a trailing slash: `""` -> `/`, `cell1` -> `/cell1`,
/// `/cell1/` -> `/cell1`. Does not validate.
pub fn normalize_namespace(namespace: &str) -> String {
    let trimmed = namespace.trim_end_matches('/');
    if trimmed.is_empty() {
        "/".to_string()
    } else if trimmed.starts_with('/') {
        trimmed.to_string()
    } else {
        format!("/{trimmed}")
    }
}

/// A node name: `[A-Za-z0-9_]+`, not starting with a digit (rmw_validate_node_name).
pub fn validate_node_name(name: &str) -> Result<(), NameError> {
    let err = |reason: &str| Err(NameError::new("node name", name, reason));
    if name.is_empty() {
        return err("must not be empty");
    }
    if !is_token(name) {
        return err("only letters, digits and '_' are allowed");
    }
    if name.starts_with(|c: char| c.is_ascii_digit()) {
        return err("must not start with a digit");
    }
    Ok(())
}

/// An absolute namespace: `/`, or `/a/b` with the token rules of [`validate_full_name`].
pub fn validate_namespace(namespace: &str) -> Result<(), NameError> {
    if namespace == "/" {
        return Ok(());
    }
    check_full_name(namespace, "namespace")
}

/// A fully qualified topic or service name (rmw_validate_full_topic_name): starts with `/`,
/// tokens of `[A-Za-z0-9_]` not starting with a digit, no `//`, no trailing `/`.
pub fn validate_full_name(name: &str) -> Result<(), NameError> {
    check_full_name(name, "topic or service name")
}

fn check_full_name(name: &str, what: &'static str) -> Result<(), NameError> {
    let err = |reason: &str| Err(NameError::new(what, name, reason));
    if !name.starts_with('/') {
        return err("must be absolute, starting with '/'");
    }
    if name.ends_with('/') {
        return err("must not end with '/'");
    }
    for token in name[1..].split('/') {
        if token.is_empty() {
            return err("must not contain '//'");
        }
        if !is_token(token) {
            return err("only letters, digits, '_' and '/' are allowed");
        }
        if token.starts_with(|c: char| c.is_ascii_digit()) {
            return err("a token must not start with a digit");
        }
    }
    Ok(())
}

/// A name as a node may give it (rcl_validate_topic_name): relative or absolute, `~`, `{subs}`.
fn check_input_name(name: &str) -> Result<(), NameError> {
    let what = "topic or service name";
    let err = |reason: &str| Err(NameError::new(what, name, reason));
    if name.is_empty() {
        return err("must not be empty");
    }
    if name.ends_with('/') {
        return err("must not end with '/'");
    }
    if name.contains("//") {
        return err("must not contain '//'");
    }
    if name.starts_with('~') && name.len() > 1 && !name.starts_with("~/") {
        return err("'~' must be followed by '/'");
    }
    let mut in_braces = false;
    for (i, c) in name.char_indices() {
        match c {
            '~' if i > 0 => return err("'~' is only allowed at the start"),
            '{' if in_braces => return err("nested '{'"),
            '{' => in_braces = true,
            '}' if !in_braces => return err("unmatched '}'"),
            '}' => in_braces = false,
            '/' if in_braces => return err("'/' inside '{}'"),
            c if c.is_ascii_alphanumeric() || matches!(c, '_' | '/' | '~') => {}
            c => return err(&format!("'{c}' is not allowed")),
        }
    }
    if in_braces {
        return err("unmatched '{'");
    }
    for token in name.split('/') {
        if token.starts_with(|c: char| c.is_ascii_digit()) {
            return err("a token must not start with a digit");
        }
    }
    Ok(())
}

/// Expands a name to a fully qualified one (rcl_expand_topic_name), without remapping.
///
/// `/x` stays; `~` -> `/ns/node`, `~/x` -> `/ns/node/x`; `{node}`, `{ns}`, `{namespace}` are
/// substituted; other relative names get the namespace: `x` -> `/ns/x` (`/x` in the root).
pub fn expand_name(name: &str, namespace: &str, node_name: &str) -> Result<String, NameError> {
    check_input_name(name)?;
    let namespace = normalize_namespace(namespace);
    let ns_prefix = if namespace == "/" { "" } else { namespace.as_str() };
    let private =
        if name == "~" { Some(String::new()) } else { name.strip_prefix("~/").map(|rest| format!("/{rest}")) };
    let mut out = match private {
        Some(rest) => format!("{ns_prefix}/{node_name}{rest}"),
        None => name.to_string(),
    };
    while let Some(open) = out.find('{') {
        let close = open + out[open..].find('}').expect("braces checked");
        let replacement = match &out[open + 1..close] {
            "node" => node_name.to_string(),
            // In the root namespace "{ns}/x" is "/x", not "//x".
            "ns" | "namespace" if namespace == "/" && out[close + 1..].starts_with('/') => String::new(),
            "ns" | "namespace" => namespace.clone(),
            other => {
                return Err(NameError::new("topic or service name", name, format!("unknown substitution {{{other}}}")));
            }
        };
        out.replace_range(open..=close, &replacement);
    }
    if !out.starts_with('/') {
        out = format!("{ns_prefix}/{out}");
    }
    validate_full_name(&out).map_err(|e| NameError::new("topic or service name", name, e.to_string()))?;
    Ok(out)
}

fn resolve(
    name: &str,
    namespace: &str,
    node_name: &str,
    remaps: &[RemapRule],
    service: bool,
) -> Result<String, NameError> {
    let expanded = expand_name(name, namespace, node_name)?;
    for rule in remaps.iter().filter(|r| r.applies_to_kind(service) && r.applies_to_node(node_name)) {
        if expand_name(&rule.from, namespace, node_name).is_ok_and(|from| from == expanded) {
            return expand_name(&rule.to, namespace, node_name);
        }
    }
    Ok(expanded)
}

/// Resolves a topic name as a ROS 2 node would: [`expand_name`], then the first remap rule
/// (plain or `rostopic://`, for every node or for `node_name`) whose expanded `FROM` equals the
/// expanded name replaces it with its expanded `TO`.
///
/// `node_name` is the node's final name (after `__node`); `namespace` its final namespace.
pub fn resolve_topic(name: &str, namespace: &str, node_name: &str, remaps: &[RemapRule]) -> Result<String, NameError> {
    resolve(name, namespace, node_name, remaps, false)
}

/// [`resolve_topic`] for a service name (plain and `rosservice://` rules apply).
pub fn resolve_service(
    name: &str,
    namespace: &str,
    node_name: &str,
    remaps: &[RemapRule],
) -> Result<String, NameError> {
    resolve(name, namespace, node_name, remaps, true)
}

/// A resolved (absolute) name as ros2-client's `Name`, for `create_topic` / `create_server`.
/// ros2-client is stricter than rcl: it also rejects `__` inside a token.
pub fn ros2_name(resolved: &str) -> Result<ros2_client::Name, NameError> {
    ros2_client::Name::parse(resolved).map_err(|e| NameError::new("topic or service name", resolved, e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros::args::{ArgsError, RosArgs};

    fn parse(args: &[&str]) -> Result<RosArgs, ArgsError> {
        RosArgs::parse(args.iter().copied())
    }

    #[test]
    fn fully_qualified_node_names() {
        assert_eq!(fully_qualified_node_name("/", "n"), "/n");
        assert_eq!(fully_qualified_node_name("", "n"), "/n");
        assert_eq!(fully_qualified_node_name("/cell1", "n"), "/cell1/n");
        assert_eq!(fully_qualified_node_name("/a/b/", "n"), "/a/b/n");
        assert_eq!(fully_qualified_node_name("cell1", "n"), "/cell1/n");
        assert_eq!(normalize_namespace("///"), "/");
        let id = NodeIdentity { name: "tracer".into(), namespace: "/cell1".into() };
        assert_eq!(id.to_string(), "/cell1/tracer");
        let n = id.ros2_node_name().unwrap();
        assert_eq!(n.fully_qualified_name(), "/cell1/tracer");
    }

    #[test]
    fn expansion_follows_rcl() {
        let e = |name: &str, ns: &str| expand_name(name, ns, "node");
        assert_eq!(e("chatter", "/").unwrap(), "/chatter");
        assert_eq!(e("chatter", "/ns").unwrap(), "/ns/chatter");
        assert_eq!(e("a/b", "/ns").unwrap(), "/ns/a/b");
        assert_eq!(e("/chatter", "/ns").unwrap(), "/chatter");
        assert_eq!(e("~", "/ns").unwrap(), "/ns/node");
        assert_eq!(e("~/x", "/ns").unwrap(), "/ns/node/x");
        assert_eq!(e("~/x", "/").unwrap(), "/node/x");
        assert_eq!(e("{node}/x", "/ns").unwrap(), "/ns/node/x");
        assert_eq!(e("{ns}/x", "/ns").unwrap(), "/ns/x");
        assert_eq!(e("{namespace}/x", "/ns").unwrap(), "/ns/x");
        assert_eq!(e("{ns}/x", "/").unwrap(), "/x");
        assert_eq!(e("/a/{node}/x", "/ns").unwrap(), "/a/node/x");
        assert!(e("/a/{ns}/x", "/ns").is_err(), "the namespace is absolute: '/a//ns/x'");
        for bad in ["", "a/", "a//b", "~x", "a~", "1a", "a/1b", "a b", "{oops}/x", "{node", "node}", "a-b", "/"] {
            assert!(e(bad, "/ns").is_err(), "{bad:?} should be rejected");
        }
    }

    #[test]
    fn remaps_match_the_expanded_name() {
        let rules = |specs: &[&str]| -> Vec<RemapRule> { specs.iter().map(|s| RemapRule::parse(s).unwrap()).collect() };
        let r = rules(&["raw_scan:=/x"]);
        assert_eq!(resolve_topic("raw_scan", "/cell1", "n", &r).unwrap(), "/x");
        assert_eq!(resolve_topic("/cell1/raw_scan", "/cell1", "n", &r).unwrap(), "/x");
        assert_eq!(resolve_topic("/raw_scan", "/cell1", "n", &r).unwrap(), "/raw_scan", "other name");
        let r = rules(&["/cell1/raw_scan:=scans"]);
        assert_eq!(resolve_topic("raw_scan", "/cell1", "n", &r).unwrap(), "/cell1/scans");
        let r = rules(&["~/in:=~/out"]);
        assert_eq!(resolve_topic("~/in", "/cell1", "n", &r).unwrap(), "/cell1/n/out");
        assert_eq!(resolve_topic("/cell1/n/in", "/cell1", "n", &r).unwrap(), "/cell1/n/out");
        let r = rules(&["rostopic://x:=/t", "rosservice://x:=/s"]);
        assert_eq!(resolve_topic("x", "/", "n", &r).unwrap(), "/t");
        assert_eq!(resolve_service("x", "/", "n", &r).unwrap(), "/s");
        let r = rules(&["__node:=x", "__ns:=/y"]);
        assert_eq!(resolve_topic("__node", "/", "n", &r).unwrap(), "/__node", "node rules never rename topics");
        assert!(resolve_topic("bad name", "/", "n", &[]).is_err());
    }

    #[test]
    fn validation() {
        assert!(validate_node_name("tracer_calibrator").is_ok());
        for bad in ["", "9a", "a-b", "a/b", "ä"] {
            assert!(validate_node_name(bad).is_err(), "{bad:?}");
        }
        assert!(validate_namespace("/").is_ok());
        assert!(validate_namespace("/cell1/sub").is_ok());
        for bad in ["", "cell1", "/cell1/", "//", "/a//b", "/1a", "/a b"] {
            assert!(validate_namespace(bad).is_err(), "{bad:?}");
        }
        assert!(validate_full_name("/a/b_c").is_ok());
        for bad in ["/", "a", "/a/", "/a/~", "/{x}"] {
            assert!(validate_full_name(bad).is_err(), "{bad:?}");
        }
        let err = validate_namespace("/1a").unwrap_err();
        assert_eq!(err.to_string(), "invalid namespace '/1a': a token must not start with a digit");
        // node identity validates the result
        let args = parse(&["p", "--ros-args", "-r", "__node:=ok"]).unwrap();
        assert!(args.node_identity("ok", "/bad//ns").is_err());
        assert!(args.node_identity("x", "relative").is_ok());
    }

    #[test]
    fn ros2_client_names() {
        assert_eq!(ros2_name("/cell1/raw_scan").unwrap().to_string(), "/cell1/raw_scan");
        assert!(ros2_name("/a__b").is_err(), "ros2-client rejects double underscores");
    }
}
