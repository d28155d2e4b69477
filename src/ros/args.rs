//! ROS 2 command-line arguments, name resolution, parameter value typing, and the ROS
//! environment variables: what `rcl` does for a C++ or Python node, and ros2-client does not.
//!
//! # Command line (rcl semantics)
//!
//! ROS arguments sit between `--ros-args` and `--` (or the end of `argv`); there may be several
//! such blocks, and a `--ros-args` inside a block is ignored. Everything outside the blocks is
//! the program's own, returned in [`RosArgs::program_args`] in order (including `argv[0]`, so it
//! can go straight to clap). `--` only ends a block; outside a block it is a program argument.
//!
//! Inside a block:
//!
//! | argument | meaning |
//! |---|---|
//! | `-r`/`--remap [NODE:]FROM:=TO` | name remap; `__node`/`__name` renames the node, `__ns` sets its namespace (must be absolute); `rostopic://`/`rosservice://` limit `FROM` to topics/services |
//! | `-p`/`--param [NODE:]NAME:=VALUE` | parameter override; `VALUE` is a one-line YAML value, typed like a params file ([`ParamValue::parse_yaml`]) |
//! | `--params-file FILE` | parameters file; may repeat |
//! | `--log-level LEVEL` / `--log-level LOGGER:=LEVEL` | `debug info warn error fatal unset`, any case |
//! | `--log-config-file FILE`, `-e`/`--enclave NAME`, `--log-file-name NAME` | recorded |
//! | `--enable-`/`--disable-` + `stdout-logs`/`rosout-logs`/`external-lib-logs` | accepted, ignored |
//!
//! Anything else inside a block is an error, as in rclcpp ("unknown ROS arguments"); so is a
//! flag with nothing after it, or a malformed rule. Errors name the flag and the argument.
//!
//! Order matters as in rcl: among several rules for the same thing the **first** matching
//! remap wins, and parameter files and `-p` overrides are applied in command-line order, the
//! later ones winning ([`RosArgs::param_sources`] keeps that order).
//!
//! # Names
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
//! # Parameter values
//!
//! [`ParamValue::from_yaml_scalar`] types a YAML scalar exactly as `rcl_yaml_param_parser`
//! does: quoted -> string; else YAML 1.1 booleans; else a C `strtoll(.., 0)` integer (so `0x1f`
//! is 31 and `010` is 8!); else a C `strtod` double (also `.inf`, `-.inf`, `.nan`, `nan`,
//! `inf`, `1e3`, hex floats); else a string.
//!
//! # Environment
//!
//! [`RosEnv`] reads `ROS_DOMAIN_ID` (0..=232), `ROS_AUTOMATIC_DISCOVERY_RANGE` (an unknown value
//! means localhost, as in rcl), the deprecated `ROS_LOCALHOST_ONLY=1` (honoured, as in Jazzy) and
//! `ROS_STATIC_PEERS`.

use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

pub use crate::params::ParamValue;
use crate::params::value::c_strtoll;

// ------------------------------------------------------------------------------------------
// Errors

/// A command-line argument that could not be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ArgsError {
    /// A flag that takes a value was the last argument.
    #[error("{flag} expects {expected}, but nothing follows it")]
    MissingValue {
        /// The flag, as given (`-r`, `--param`, ...).
        flag: String,
        /// What it takes, e.g. `FROM:=TO`.
        expected: &'static str,
    },
    /// A flag's value is malformed.
    #[error("{flag} expects {expected}, got '{got}': {reason}")]
    BadValue {
        /// The flag, as given.
        flag: String,
        /// What it takes.
        expected: &'static str,
        /// The value given.
        got: String,
        /// What is wrong with it.
        reason: String,
    },
    /// An argument inside a `--ros-args` block that is no ROS argument.
    #[error("unknown ROS argument '{0}' (end the ROS arguments with '--' to pass it to the program)")]
    UnknownRosArg(String),
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

/// An unusable ROS environment variable.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum EnvError {
    /// `ROS_DOMAIN_ID` is not an integer in `0..=232`.
    #[error("ROS_DOMAIN_ID must be an integer in 0..={max}, got '{0}'", max = ROS_DOMAIN_ID_MAX)]
    DomainId(String),
}

// ------------------------------------------------------------------------------------------
// Log levels

/// A ROS log severity, as `--log-level` takes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum LogLevel {
    /// `unset`: inherit / default.
    Unset,
    /// `debug`.
    Debug,
    /// `info`.
    Info,
    /// `warn` (also `warning`).
    Warn,
    /// `error`.
    Error,
    /// `fatal`.
    Fatal,
}

impl LogLevel {
    /// The `log` crate filter for this level; `None` for `Unset` (keep the default).
    /// `Fatal` maps to `Error`, the highest `log` has.
    pub fn level_filter(self) -> Option<log::LevelFilter> {
        match self {
            LogLevel::Unset => None,
            LogLevel::Debug => Some(log::LevelFilter::Debug),
            LogLevel::Info => Some(log::LevelFilter::Info),
            LogLevel::Warn => Some(log::LevelFilter::Warn),
            LogLevel::Error | LogLevel::Fatal => Some(log::LevelFilter::Error),
        }
    }
}

impl FromStr for LogLevel {
    type Err = String;

    /// Case-insensitive `debug`, `info`, `warn`/`warning`, `error`, `fatal`, `unset`.
    fn from_str(s: &str) -> Result<Self, String> {
        Ok(match s.to_ascii_lowercase().as_str() {
            "unset" => LogLevel::Unset,
            "debug" => LogLevel::Debug,
            "info" => LogLevel::Info,
            "warn" | "warning" => LogLevel::Warn,
            "error" => LogLevel::Error,
            "fatal" => LogLevel::Fatal,
            _ => return Err(format!("unknown log level '{s}' (debug, info, warn, error, fatal, unset)")),
        })
    }
}

// ------------------------------------------------------------------------------------------
// Rules

/// What a remap rule renames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RemapKind {
    /// `__node:=NAME` (or `__name:=`): the node's name.
    NodeName,
    /// `__ns:=/NS`: the node's namespace.
    Namespace,
    /// `FROM:=TO`: topic and service names.
    Name,
    /// `rostopic://FROM:=TO`: topic names only.
    Topic,
    /// `rosservice://FROM:=TO`: service names only.
    Service,
}

/// One `-r [NODE:]FROM:=TO` rule.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RemapRule {
    /// The node it is limited to (`NODE:` prefix), or `None` for every node.
    pub node: Option<String>,
    /// What it renames.
    pub kind: RemapKind,
    /// The match side, without `rostopic://`/`rosservice://`; empty for `__node`/`__ns`.
    pub from: String,
    /// The replacement: a name, a node name, or an absolute namespace (no trailing `/`).
    pub to: String,
}

impl RemapRule {
    /// Parses a rule as rcl does; the error says what is wrong.
    pub fn parse(rule: &str) -> Result<RemapRule, String> {
        let (lhs, rhs) = rule.split_once(":=").ok_or("no ':=' in it")?;
        let (node, lhs) = split_node_prefix(lhs)?;
        if lhs.is_empty() {
            return Err("nothing to remap before ':='".into());
        }
        if rhs.is_empty() {
            return Err("nothing after ':='".into());
        }
        let (kind, from, to) = match lhs {
            "__node" | "__name" => {
                validate_node_name(rhs).map_err(|e| e.to_string())?;
                (RemapKind::NodeName, String::new(), rhs.to_string())
            }
            "__ns" => {
                if !rhs.starts_with('/') {
                    return Err("the namespace must be absolute, starting with '/'".into());
                }
                let ns = normalize_namespace(rhs);
                validate_namespace(&ns).map_err(|e| e.to_string())?;
                (RemapKind::Namespace, String::new(), ns)
            }
            _ => {
                let (kind, from) = if let Some(m) = lhs.strip_prefix("rostopic://") {
                    (RemapKind::Topic, m)
                } else if let Some(m) = lhs.strip_prefix("rosservice://") {
                    (RemapKind::Service, m)
                } else {
                    (RemapKind::Name, lhs)
                };
                check_rule_name(from, "FROM")?;
                check_rule_name(rhs, "TO")?;
                (kind, from.to_string(), rhs.to_string())
            }
        };
        Ok(RemapRule { node: node.map(str::to_string), kind, from, to })
    }

    /// Whether the rule applies to a node of this name.
    pub fn applies_to_node(&self, node_name: &str) -> bool {
        self.node.as_deref().is_none_or(|n| n == node_name)
    }

    fn applies_to(&self, service: bool) -> bool {
        match self.kind {
            RemapKind::Name => true,
            RemapKind::Topic => !service,
            RemapKind::Service => service,
            RemapKind::NodeName | RemapKind::Namespace => false,
        }
    }
}

fn is_token(s: &str) -> bool {
    !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// `node:rest` -> (Some(node), rest); a `://` is a URL scheme, not a node prefix.
fn split_node_prefix(lhs: &str) -> Result<(Option<&str>, &str), String> {
    match lhs.find(':') {
        Some(i) if !lhs[i..].starts_with("://") => {
            let node = &lhs[..i];
            if !is_token(node) {
                return Err(format!("'{node}' before ':' is not a node name"));
            }
            Ok((Some(node), &lhs[i + 1..]))
        }
        _ => Ok((None, lhs)),
    }
}

/// A remap rule side: optional `/` or `~/`, then tokens separated by `/`.
fn check_rule_name(name: &str, side: &str) -> Result<(), String> {
    let body = name.strip_prefix("~/").or_else(|| name.strip_prefix('/')).unwrap_or(name);
    for token in body.split('/') {
        if token == "*" || token == "**" {
            return Err(format!("{side} '{name}': wildcards are not implemented (nor are they in rcl)"));
        }
        if token.starts_with('\\') {
            return Err(format!("{side} '{name}': backreferences are not implemented (nor are they in rcl)"));
        }
        if !is_token(token) {
            return Err(format!("{side} '{name}' is not a name: tokens of [A-Za-z0-9_] separated by '/'"));
        }
        if token.starts_with(|c: char| c.is_ascii_digit()) {
            return Err(format!("{side} '{name}': a name token must not start with a digit"));
        }
    }
    Ok(())
}

/// One `-p [NODE:]NAME:=VALUE` override.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamOverride {
    /// The node it is limited to (`NODE:` prefix), or `None` for every node (`/**`).
    pub node: Option<String>,
    /// The parameter name, e.g. `plate.side`.
    pub name: String,
    /// The typed value.
    pub value: ParamValue,
}

impl ParamOverride {
    /// Parses an override as rcl does; the error says what is wrong.
    pub fn parse(rule: &str) -> Result<ParamOverride, String> {
        let (lhs, value) = rule.split_once(":=").ok_or("no ':=' in it")?;
        let (node, name) = match lhs.split_once(':') {
            Some((node, name)) => {
                if !is_token(node) {
                    return Err(format!("'{node}' before ':' is not a node name"));
                }
                (Some(node.to_string()), name)
            }
            None => (None, lhs),
        };
        if name.is_empty() || !name.split('.').all(is_token) {
            return Err(format!("'{name}' is not a parameter name: tokens of [A-Za-z0-9_] separated by '.'"));
        }
        let value = ParamValue::parse_yaml(value)?;
        Ok(ParamOverride { node, name: name.to_string(), value })
    }

    /// Whether the override applies to `node`: no prefix, or the prefix is the node's name or
    /// fully qualified name (rclcpp only compares `/` + prefix with the fully qualified name,
    /// so it never matches a namespaced node; matching the base name too is friendlier).
    pub fn applies_to(&self, node: &NodeIdentity) -> bool {
        match self.node.as_deref() {
            None => true,
            Some(prefix) => {
                let fqn = node.fully_qualified_name();
                prefix == node.name || fqn == prefix || fqn.strip_prefix('/') == Some(prefix)
            }
        }
    }
}

/// A source of parameter values, in command-line order.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamSource {
    /// `--params-file FILE`.
    File(PathBuf),
    /// `-p NAME:=VALUE`.
    Override(ParamOverride),
}

// ------------------------------------------------------------------------------------------
// The command line

/// The ROS part of a command line, and the rest.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RosArgs {
    /// `-r` rules, in order (the first matching one wins).
    pub remaps: Vec<RemapRule>,
    /// `--params-file` and `-p`, in order; apply in this order, later ones win.
    pub param_sources: Vec<ParamSource>,
    /// `--log-level LEVEL` (the last one given).
    pub log_level: Option<LogLevel>,
    /// `--log-level LOGGER:=LEVEL`, in order.
    pub logger_levels: Vec<(String, LogLevel)>,
    /// `--log-config-file FILE` (the last one given).
    pub log_config_file: Option<PathBuf>,
    /// `-e`/`--enclave NAME` (the last one given).
    pub enclave: Option<String>,
    /// ROS arguments that were accepted but have no effect here (`--disable-rosout-logs`,
    /// `--log-file-name NAME`, ...), as given.
    pub ignored: Vec<String>,
    /// Everything outside the `--ros-args` blocks, in order (with `argv[0]` if it was given).
    pub program_args: Vec<String>,
}

/// Expected values, for error messages.
const EXPECT_REMAP: &str = "[NODE:]FROM:=TO";
const EXPECT_PARAM: &str = "[NODE:]NAME:=VALUE";
const EXPECT_FILE: &str = "a file path";
const EXPECT_LOG_LEVEL: &str = "LEVEL or LOGGER:=LEVEL";
const EXPECT_NAME: &str = "a name";

impl RosArgs {
    /// Splits `argv` (normally the whole of `std::env::args()`) into ROS arguments and the
    /// program's own; see the module documentation for the rules.
    pub fn parse<I, S>(argv: I) -> Result<RosArgs, ArgsError>
    where
        I: IntoIterator<Item = S>,
        S: Into<String>,
    {
        let argv: Vec<String> = argv.into_iter().map(Into::into).collect();
        let mut out = RosArgs::default();
        let mut in_ros_args = false;
        let mut i = 0;
        while i < argv.len() {
            let arg = argv[i].as_str();
            i += 1;
            if !in_ros_args {
                if arg == "--ros-args" {
                    in_ros_args = true;
                } else {
                    out.program_args.push(arg.to_string());
                }
                continue;
            }
            let mut value = |expected: &'static str| -> Result<String, ArgsError> {
                let v = argv.get(i).ok_or_else(|| ArgsError::MissingValue { flag: arg.to_string(), expected })?;
                i += 1;
                Ok(v.clone())
            };
            let bad = |expected: &'static str, got: &str, reason: String| ArgsError::BadValue {
                flag: arg.to_string(),
                expected,
                got: got.to_string(),
                reason,
            };
            match arg {
                "--ros-args" => {}
                "--" => in_ros_args = false,
                "-r" | "--remap" => {
                    let v = value(EXPECT_REMAP)?;
                    out.remaps.push(RemapRule::parse(&v).map_err(|e| bad(EXPECT_REMAP, &v, e))?);
                }
                "-p" | "--param" => {
                    let v = value(EXPECT_PARAM)?;
                    let o = ParamOverride::parse(&v).map_err(|e| bad(EXPECT_PARAM, &v, e))?;
                    out.param_sources.push(ParamSource::Override(o));
                }
                "--params-file" => {
                    let v = value(EXPECT_FILE)?;
                    if v.is_empty() {
                        return Err(bad(EXPECT_FILE, &v, "empty path".into()));
                    }
                    out.param_sources.push(ParamSource::File(PathBuf::from(v)));
                }
                "--log-level" => {
                    let v = value(EXPECT_LOG_LEVEL)?;
                    match v.split_once(":=") {
                        Some((logger, level)) => {
                            if logger.is_empty() {
                                return Err(bad(EXPECT_LOG_LEVEL, &v, "empty logger name".into()));
                            }
                            let level = level.parse().map_err(|e| bad(EXPECT_LOG_LEVEL, &v, e))?;
                            out.logger_levels.push((logger.to_string(), level));
                        }
                        None => out.log_level = Some(v.parse().map_err(|e| bad(EXPECT_LOG_LEVEL, &v, e))?),
                    }
                }
                "--log-config-file" => {
                    let v = value(EXPECT_FILE)?;
                    out.log_config_file = Some(PathBuf::from(v));
                }
                "-e" | "--enclave" => {
                    let v = value(EXPECT_NAME)?;
                    out.enclave = Some(v);
                }
                "--log-file-name" => {
                    let v = value(EXPECT_NAME)?;
                    out.ignored.push(format!("{arg} {v}"));
                }
                _ if is_logging_toggle(arg) => out.ignored.push(arg.to_string()),
                _ => return Err(ArgsError::UnknownRosArg(arg.to_string())),
            }
        }
        Ok(out)
    }

    /// [`RosArgs::parse`] of this process's arguments (non-UTF-8 bytes replaced).
    pub fn from_env() -> Result<RosArgs, ArgsError> {
        RosArgs::parse(std::env::args_os().map(|a| a.to_string_lossy().into_owned()))
    }

    /// The node's name and namespace after `__node` and `__ns` rules (first match wins; a
    /// `NODE:` prefix is compared with `default_name`). `default_namespace` may be relative or
    /// empty (`""` = root).
    pub fn node_identity(&self, default_name: &str, default_namespace: &str) -> Result<NodeIdentity, NameError> {
        let first = |kind: RemapKind| {
            self.remaps.iter().find(|r| r.kind == kind && r.applies_to_node(default_name)).map(|r| r.to.as_str())
        };
        let name = first(RemapKind::NodeName).unwrap_or(default_name).to_string();
        let namespace = normalize_namespace(first(RemapKind::Namespace).unwrap_or(default_namespace));
        validate_node_name(&name)?;
        validate_namespace(&namespace)?;
        Ok(NodeIdentity { name, namespace })
    }

    /// The `--params-file` paths, in order.
    pub fn params_files(&self) -> impl Iterator<Item = &Path> {
        self.param_sources.iter().filter_map(|s| match s {
            ParamSource::File(path) => Some(path.as_path()),
            ParamSource::Override(_) => None,
        })
    }

    /// The `-p` overrides, in order.
    pub fn param_overrides(&self) -> impl Iterator<Item = &ParamOverride> {
        self.param_sources.iter().filter_map(|s| match s {
            ParamSource::Override(o) => Some(o),
            ParamSource::File(_) => None,
        })
    }

    /// The `-p` overrides that apply to `node`, in order (later ones win).
    pub fn param_overrides_for<'a>(&'a self, node: &'a NodeIdentity) -> impl Iterator<Item = &'a ParamOverride> {
        self.param_overrides().filter(move |o| o.applies_to(node))
    }

    /// [`resolve_topic`] for `node` with these remaps.
    pub fn resolve_topic(&self, name: &str, node: &NodeIdentity) -> Result<String, NameError> {
        resolve_topic(name, &node.namespace, &node.name, &self.remaps)
    }

    /// [`resolve_service`] for `node` with these remaps.
    pub fn resolve_service(&self, name: &str, node: &NodeIdentity) -> Result<String, NameError> {
        resolve_service(name, &node.namespace, &node.name, &self.remaps)
    }
}

fn is_logging_toggle(arg: &str) -> bool {
    let suffix = arg.strip_prefix("--enable-").or_else(|| arg.strip_prefix("--disable-"));
    matches!(suffix, Some("stdout-logs" | "rosout-logs" | "external-lib-logs"))
}

// ------------------------------------------------------------------------------------------
// Names

/// A node's final name and namespace.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct NodeIdentity {
    /// The base name, e.g. `tracer`.
    pub name: String,
    /// The absolute namespace, `/` for the root, never with a trailing `/` otherwise.
    pub namespace: String,
}

impl NodeIdentity {
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
    for rule in remaps.iter().filter(|r| r.applies_to(service) && r.applies_to_node(node_name)) {
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

// ------------------------------------------------------------------------------------------
// Environment

/// The largest `ROS_DOMAIN_ID` the RTPS port mapping allows.
pub const ROS_DOMAIN_ID_MAX: u32 = 232;

/// `ROS_AUTOMATIC_DISCOVERY_RANGE`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DiscoveryRange {
    /// `OFF`: no discovery at all (static peers are ignored, as rmw_fastrtps does).
    Off,
    /// `LOCALHOST`: only participants on this host.
    Localhost,
    /// `SUBNET`: the DDS default, multicast on the local networks. Also the default when unset.
    Subnet,
    /// `SYSTEM_DEFAULT`: whatever the middleware does by default.
    SystemDefault,
}

impl DiscoveryRange {
    /// Whether automatic discovery stays on this host (`LOCALHOST`, and `OFF`, which
    /// discovers nothing). What each range does: [`crate::ros::discovery`].
    pub fn is_local_only(self) -> bool {
        matches!(self, DiscoveryRange::Off | DiscoveryRange::Localhost)
    }
}

/// The ROS environment of the process.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RosEnv {
    /// `ROS_DOMAIN_ID`, 0 when unset or empty.
    pub domain_id: u32,
    /// `ROS_AUTOMATIC_DISCOVERY_RANGE` (or `ROS_LOCALHOST_ONLY=1`).
    pub discovery_range: DiscoveryRange,
    /// `ROS_STATIC_PEERS`, split at `;`, empty entries dropped.
    pub static_peers: Vec<String>,
    /// Things to log as warnings (an unknown discovery range, a deprecated variable).
    pub warnings: Vec<String>,
}

/// `ROS_DOMAIN_ID`: unset or empty -> 0; else an integer (C `strtoul` base 0 forms: `7`,
/// `0x1f`, `010` = 8) in `0..=232`, surrounding whitespace ignored.
pub fn parse_domain_id(value: Option<&str>) -> Result<u32, EnvError> {
    let Some(text) = value.map(str::trim).filter(|t| !t.is_empty()) else {
        return Ok(0);
    };
    match c_strtoll(text).and_then(|v| u32::try_from(v).ok()) {
        Some(id) if id <= ROS_DOMAIN_ID_MAX && !text.starts_with(['-', '+']) => Ok(id),
        _ => Err(EnvError::DomainId(value.unwrap_or_default().to_string())),
    }
}

/// `ROS_AUTOMATIC_DISCOVERY_RANGE`: unset or empty -> `Subnet`; `OFF`, `LOCALHOST`, `SUBNET`,
/// `SYSTEM_DEFAULT` (exact case); anything else -> `Localhost` with a warning, as rcl does.
pub fn parse_discovery_range(value: Option<&str>) -> (DiscoveryRange, Option<String>) {
    match value.unwrap_or("") {
        "" | "SUBNET" => (DiscoveryRange::Subnet, None),
        "OFF" => (DiscoveryRange::Off, None),
        "LOCALHOST" => (DiscoveryRange::Localhost, None),
        "SYSTEM_DEFAULT" => (DiscoveryRange::SystemDefault, None),
        other => (
            DiscoveryRange::Localhost,
            Some(format!(
                "Invalid value '{other}' specified for 'ROS_AUTOMATIC_DISCOVERY_RANGE', assuming localhost only"
            )),
        ),
    }
}

impl RosEnv {
    /// Reads the variables through `get` (name -> value), so it can be tested without touching
    /// the process environment.
    pub fn from_lookup(get: impl Fn(&str) -> Option<String>) -> Result<RosEnv, EnvError> {
        let domain_id = parse_domain_id(get("ROS_DOMAIN_ID").as_deref())?;
        let (mut discovery_range, warning) = parse_discovery_range(get("ROS_AUTOMATIC_DISCOVERY_RANGE").as_deref());
        let mut warnings: Vec<String> = warning.into_iter().collect();
        let mut static_peers: Vec<String> = get("ROS_STATIC_PEERS")
            .unwrap_or_default()
            .split(';')
            .map(str::trim)
            .filter(|p| !p.is_empty())
            .map(str::to_string)
            .collect();
        if get("ROS_LOCALHOST_ONLY").as_deref().map(str::trim) == Some("1") {
            warnings.push(
                "ROS_LOCALHOST_ONLY is deprecated but still honored if it is enabled; \
                 use ROS_AUTOMATIC_DISCOVERY_RANGE and ROS_STATIC_PEERS instead"
                    .to_string(),
            );
            discovery_range = DiscoveryRange::Localhost;
            static_peers.clear();
        }
        Ok(RosEnv { domain_id, discovery_range, static_peers, warnings })
    }

    /// Reads the real process environment.
    pub fn from_env() -> Result<RosEnv, EnvError> {
        RosEnv::from_lookup(|name| std::env::var_os(name).map(|v| v.to_string_lossy().into_owned()))
    }
}

// ------------------------------------------------------------------------------------------

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn parse(args: &[&str]) -> Result<RosArgs, ArgsError> {
        RosArgs::parse(args.iter().copied())
    }

    fn scalar(text: &str) -> ParamValue {
        ParamValue::from_yaml_scalar(text, false)
    }

    // ------------------------------------------------------------ YAML scalar typing

    #[test]
    fn yaml_booleans_follow_rcl() {
        for t in ["true", "True", "TRUE", "yes", "Yes", "YES", "on", "On", "ON", "y", "Y"] {
            assert_eq!(scalar(t), ParamValue::Bool(true), "{t}");
        }
        for f in ["false", "False", "FALSE", "no", "No", "NO", "off", "Off", "OFF", "n", "N"] {
            assert_eq!(scalar(f), ParamValue::Bool(false), "{f}");
        }
        for s in ["tRue", "yES", "oN", "t", "f", "1 ", "truee"] {
            assert!(!matches!(scalar(s), ParamValue::Bool(_)), "{s}");
        }
        assert_eq!(ParamValue::from_yaml_scalar("true", true), ParamValue::String("true".into()));
    }

    #[test]
    fn yaml_integers_follow_strtoll_base_0() {
        assert_eq!(scalar("0"), ParamValue::Integer(0));
        assert_eq!(scalar("400"), ParamValue::Integer(400));
        assert_eq!(scalar("-12"), ParamValue::Integer(-12));
        assert_eq!(scalar("+7"), ParamValue::Integer(7));
        assert_eq!(scalar("0x1F"), ParamValue::Integer(31));
        assert_eq!(scalar("0X1f"), ParamValue::Integer(31));
        assert_eq!(scalar("-0x10"), ParamValue::Integer(-16));
        assert_eq!(scalar("010"), ParamValue::Integer(8), "octal, as in C");
        assert_eq!(scalar("9223372036854775807"), ParamValue::Integer(i64::MAX));
        assert_eq!(scalar("-9223372036854775808"), ParamValue::Integer(i64::MIN));
        assert_eq!(scalar(" 5"), ParamValue::Integer(5), "strtoll skips leading space");
        // not fully consumed, or overflowing: not an integer
        assert_eq!(scalar("08"), ParamValue::Double(8.0), "not octal; strtod reads it");
        assert_eq!(scalar("9223372036854775808"), ParamValue::Double(2f64.powi(63)));
        assert_eq!(scalar("0x"), ParamValue::String("0x".into()));
        assert_eq!(scalar("12abc"), ParamValue::String("12abc".into()));
        assert_eq!(scalar("5 "), ParamValue::String("5 ".into()));
        assert_eq!(scalar("1_000"), ParamValue::String("1_000".into()));
        assert_eq!(scalar("-"), ParamValue::String("-".into()));
        assert_eq!(scalar("+-5"), ParamValue::String("+-5".into()));
        assert_eq!(ParamValue::from_yaml_scalar("42", true), ParamValue::String("42".into()));
    }

    #[test]
    fn yaml_doubles_follow_strtod() {
        assert_eq!(scalar("0.045"), ParamValue::Double(0.045));
        assert_eq!(scalar("1.0e-6"), ParamValue::Double(1.0e-6));
        assert_eq!(scalar("1e-6"), ParamValue::Double(1e-6));
        assert_eq!(scalar("1E3"), ParamValue::Double(1000.0));
        assert_eq!(scalar("-2.5"), ParamValue::Double(-2.5));
        assert_eq!(scalar("5."), ParamValue::Double(5.0));
        assert_eq!(scalar(".5"), ParamValue::Double(0.5));
        assert_eq!(scalar("+.5e+1"), ParamValue::Double(5.0));
        assert_eq!(scalar("0x1p3"), ParamValue::Double(8.0));
        assert_eq!(scalar("0x1.8p1"), ParamValue::Double(3.0));
        assert_eq!(scalar("inf"), ParamValue::Double(f64::INFINITY));
        assert_eq!(scalar("-Infinity"), ParamValue::Double(f64::NEG_INFINITY));
        for t in [".inf", ".Inf", ".INF", "+.inf", "+.Inf", "+.INF"] {
            assert_eq!(scalar(t), ParamValue::Double(f64::INFINITY), "{t}");
        }
        for t in ["-.inf", "-.Inf", "-.INF"] {
            assert_eq!(scalar(t), ParamValue::Double(f64::NEG_INFINITY), "{t}");
        }
        for t in [".nan", ".NaN", ".NAN", "nan", "NaN", "nan(123)"] {
            assert!(matches!(scalar(t), ParamValue::Double(d) if d.is_nan()), "{t}");
        }
        // not doubles
        for s in ["1e", "1e+", "e5", ".", "1.2.3", "1e999", "-1e999", "1e-400", "0x1p", ".infinity", "1,5", "1.5x"] {
            assert_eq!(scalar(s), ParamValue::String(s.into()), "{s}");
        }
        assert_eq!(scalar("0e-400"), ParamValue::Double(0.0), "an exact zero does not underflow");
    }

    #[test]
    fn yaml_strings_and_edge_cases() {
        assert_eq!(scalar("full"), ParamValue::String("full".into()));
        assert_eq!(scalar("tracer_axis"), ParamValue::String("tracer_axis".into()));
        assert_eq!(scalar("null"), ParamValue::String("null".into()), "rcl has no null");
        assert_eq!(scalar("~"), ParamValue::String("~".into()));
        assert_eq!(scalar(""), ParamValue::String(String::new()));
    }

    // ------------------------------------------------------------ -p values

    fn yaml(text: &str) -> ParamValue {
        ParamValue::parse_yaml(text).unwrap_or_else(|e| panic!("{text}: {e}"))
    }

    #[test]
    fn parse_yaml_scalars_quotes_and_tags() {
        assert_eq!(yaml("0.0349"), ParamValue::Double(0.0349));
        assert_eq!(yaml("  7  "), ParamValue::Integer(7));
        assert_eq!(yaml("'7'"), ParamValue::String("7".into()));
        assert_eq!(yaml("\"true\""), ParamValue::String("true".into()));
        assert_eq!(yaml("'it''s'"), ParamValue::String("it's".into()));
        assert_eq!(yaml(r#""a\tb\n\"c\" \u00e9 \x41""#), ParamValue::String("a\tb\n\"c\" é A".into()));
        assert_eq!(yaml("''"), ParamValue::String(String::new()));
        assert_eq!(yaml("!!str 42"), ParamValue::String("42".into()));
        assert_eq!(yaml("!!float 42"), ParamValue::Integer(42), "rcl only honours !!str");
        assert_eq!(yaml("hello world"), ParamValue::String("hello world".into()));
        assert_eq!(yaml("a,b"), ParamValue::String("a,b".into()));
        assert_eq!(yaml("1.5 # metres"), ParamValue::Double(1.5));
        assert_eq!(yaml("a#b"), ParamValue::String("a#b".into()));
        assert_eq!(yaml("'x' # comment"), ParamValue::String("x".into()));
        assert_eq!(yaml("http://host/x"), ParamValue::String("http://host/x".into()));
        assert_eq!(yaml("[1 2]"), ParamValue::StringArray(vec!["1 2".into()]), "valid YAML: one plain scalar");
    }

    #[test]
    fn parse_yaml_sequences() {
        assert_eq!(yaml("[1, 2, 3]"), ParamValue::IntegerArray(vec![1, 2, 3]));
        assert_eq!(yaml("[1.0,2.5]"), ParamValue::DoubleArray(vec![1.0, 2.5]));
        assert_eq!(yaml("[true, off]"), ParamValue::BoolArray(vec![true, false]));
        assert_eq!(yaml("[a, 'b c', \"d\"]"), ParamValue::StringArray(vec!["a".into(), "b c".into(), "d".into()]));
        assert_eq!(yaml("['1', '2']"), ParamValue::StringArray(vec!["1".into(), "2".into()]));
        assert_eq!(yaml("[ 1 , 2 , ]"), ParamValue::IntegerArray(vec![1, 2]));
        assert_eq!(yaml("[.inf, -.inf]"), ParamValue::DoubleArray(vec![f64::INFINITY, f64::NEG_INFINITY]));
    }

    #[test]
    fn parse_yaml_rejects_what_rcl_rejects() {
        for bad in [
            "",
            "   ",
            "[]",
            "[1, 2.5]",
            "[1, a]",
            "[[1]]",
            "[1, 2",
            "{a: 1}",
            "a: b",
            "a:",
            "'open",
            "\"open",
            "\"bad \\q escape\"",
            "&anchor 1",
            "*alias",
            "|",
            "- 1",
            "'a' b",
            "[1,,2]",
            "# just a comment",
        ] {
            assert!(ParamValue::parse_yaml(bad).is_err(), "{bad:?} should be rejected");
        }
    }

    #[test]
    fn to_yaml_round_trips() {
        let values = vec![
            ParamValue::Bool(true),
            ParamValue::Bool(false),
            ParamValue::Integer(0),
            ParamValue::Integer(-400),
            ParamValue::Integer(i64::MIN),
            ParamValue::Double(0.0),
            ParamValue::Double(-0.0),
            ParamValue::Double(1.0),
            ParamValue::Double(0.045),
            ParamValue::Double(1e-6),
            ParamValue::Double(-1.25e21),
            ParamValue::Double(f64::MAX),
            ParamValue::Double(f64::MIN_POSITIVE),
            ParamValue::Double(f64::INFINITY),
            ParamValue::Double(f64::NEG_INFINITY),
            ParamValue::Double(std::f64::consts::PI),
            ParamValue::String("full".into()),
            ParamValue::String("tracer_axis".into()),
            ParamValue::String("/cell1/params.yaml".into()),
            ParamValue::String(String::new()),
            ParamValue::String("true".into()),
            ParamValue::String("y".into()),
            ParamValue::String("400".into()),
            ParamValue::String("0x10".into()),
            ParamValue::String("1.5".into()),
            ParamValue::String(".inf".into()),
            ParamValue::String("nan".into()),
            ParamValue::String("null".into()),
            ParamValue::String("~".into()),
            ParamValue::String("-abc".into()),
            ParamValue::String("it's: a # test, [x]".into()),
            ParamValue::String(" padded ".into()),
            ParamValue::String("line\nbreak\t\"q\" \\".into()),
            ParamValue::String("ünïcode".into()),
            ParamValue::BoolArray(vec![true, false]),
            ParamValue::IntegerArray(vec![1, -2, 3]),
            ParamValue::DoubleArray(vec![1.0, 2.5, -0.001]),
            ParamValue::StringArray(vec!["a".into(), "1".into(), "b, c".into(), "'q'".into()]),
        ];
        for value in values {
            let text = value.to_yaml();
            assert_eq!(ParamValue::parse_yaml(&text).as_ref(), Ok(&value), "{value:?} -> {text}");
            assert_eq!(value.to_string(), text);
        }
        let nan = ParamValue::parse_yaml(&ParamValue::Double(f64::NAN).to_yaml()).unwrap();
        assert!(matches!(nan, ParamValue::Double(d) if d.is_nan()));
        assert_eq!(ParamValue::Double(1.0).to_yaml(), "1.0");
        assert_eq!(ParamValue::String("full".into()).to_yaml(), "full");
        assert_eq!(ParamValue::String("true".into()).to_yaml(), "'true'");
        assert_eq!(ParamValue::DoubleArray(vec![1.0, 2.5]).to_yaml(), "[1.0, 2.5]");
    }

    #[test]
    fn param_values_convert_to_ros2_client() {
        use ros2_client::ParameterValue as P;
        assert_eq!(P::from(ParamValue::Bool(true)), P::Boolean(true));
        assert_eq!(P::from(ParamValue::Integer(4)), P::Integer(4));
        assert_eq!(P::from(ParamValue::Double(0.5)), P::Double(0.5));
        assert_eq!(P::from(ParamValue::String("s".into())), P::String("s".into()));
        assert_eq!(P::from(ParamValue::BoolArray(vec![true])), P::BooleanArray(vec![true]));
        assert_eq!(P::from(ParamValue::IntegerArray(vec![1])), P::IntegerArray(vec![1]));
        assert_eq!(P::from(ParamValue::DoubleArray(vec![1.5])), P::DoubleArray(vec![1.5]));
        assert_eq!(P::from(ParamValue::StringArray(vec!["a".into()])), P::StringArray(vec!["a".into()]));
        assert_eq!(ParamValue::IntegerArray(vec![]).type_name(), "integer_array");
    }

    // ------------------------------------------------------------ command line

    #[test]
    fn the_contract_command_line() {
        let args = parse(&[
            "tracer_calib_node",
            "--ros-args",
            "-r",
            "__ns:=/cell1",
            "-r",
            "__node:=tracer",
            "-r",
            "raw_scan:=/x",
            "-p",
            "plate.side:=0.05",
            "--params-file",
            "cal.yaml",
        ])
        .unwrap();
        assert_eq!(args.program_args, vec!["tracer_calib_node"]);
        let node = args.node_identity("tracer_calibrator", "/").unwrap();
        assert_eq!(node, NodeIdentity { name: "tracer".into(), namespace: "/cell1".into() });
        assert_eq!(node.fully_qualified_name(), "/cell1/tracer");
        assert_eq!(args.resolve_topic("raw_scan", &node).unwrap(), "/x");
        assert_eq!(args.resolve_topic("contour", &node).unwrap(), "/cell1/contour");
        assert_eq!(args.resolve_topic("/diagnostics", &node).unwrap(), "/diagnostics");
        assert_eq!(args.resolve_service("calibrate", &node).unwrap(), "/cell1/calibrate");
        let overrides: Vec<_> = args.param_overrides_for(&node).collect();
        assert_eq!(overrides.len(), 1);
        assert_eq!((overrides[0].name.as_str(), &overrides[0].value), ("plate.side", &ParamValue::Double(0.05)));
        assert_eq!(args.params_files().collect::<Vec<_>>(), vec![Path::new("cal.yaml")]);
    }

    #[test]
    fn defaults_without_ros_args() {
        let args = parse(&["node", "--verbose", "-r", "x"]).unwrap();
        assert_eq!(args.program_args, vec!["node", "--verbose", "-r", "x"]);
        assert_eq!(args, RosArgs { program_args: args.program_args.clone(), ..RosArgs::default() });
        let node = args.node_identity("tracer_calibrator", "").unwrap();
        assert_eq!(node.fully_qualified_name(), "/tracer_calibrator");
        assert_eq!(args.resolve_service("calibrate", &node).unwrap(), "/calibrate");
        assert!(parse(&[]).unwrap().program_args.is_empty());
    }

    #[test]
    fn blocks_and_program_args_interleave() {
        let args = parse(&[
            "prog",
            "a",
            "--ros-args",
            "-p",
            "x:=1",
            "--",
            "b",
            "--",
            "c",
            "--ros-args",
            "--ros-args",
            "--params-file",
            "f1.yaml",
            "--",
            "--ros-args",
            "--params-file",
            "f2.yaml",
        ])
        .unwrap();
        assert_eq!(args.program_args, vec!["prog", "a", "b", "--", "c"]);
        assert_eq!(args.params_files().collect::<Vec<_>>(), vec![Path::new("f1.yaml"), Path::new("f2.yaml")]);
        assert_eq!(args.param_overrides().count(), 1);
    }

    #[test]
    fn long_flags_and_ignored_flags() {
        let args = parse(&[
            "p",
            "--ros-args",
            "--remap",
            "__node:=n",
            "--param",
            "model:=paper",
            "--log-level",
            "DEBUG",
            "--log-level",
            "rustdds:=error",
            "--log-level",
            "info",
            "--enable-rosout-logs",
            "--disable-rosout-logs",
            "--disable-stdout-logs",
            "--enable-external-lib-logs",
            "--log-config-file",
            "log.conf",
            "-e",
            "/enclave",
            "--log-file-name",
            "x.log",
        ])
        .unwrap();
        assert_eq!(args.node_identity("d", "/").unwrap().name, "n");
        assert_eq!(args.param_overrides().next().unwrap().value, ParamValue::String("paper".into()));
        assert_eq!(args.log_level, Some(LogLevel::Info), "the last one");
        assert_eq!(args.logger_levels, vec![("rustdds".to_string(), LogLevel::Error)]);
        assert_eq!(args.log_config_file.as_deref(), Some(Path::new("log.conf")));
        assert_eq!(args.enclave.as_deref(), Some("/enclave"));
        assert_eq!(args.ignored.len(), 5);
        assert_eq!(LogLevel::Warn.level_filter(), Some(log::LevelFilter::Warn));
        assert_eq!(LogLevel::Fatal.level_filter(), Some(log::LevelFilter::Error));
        assert_eq!(LogLevel::Unset.level_filter(), None);
        assert_eq!("Warning".parse::<LogLevel>(), Ok(LogLevel::Warn));
    }

    #[test]
    fn params_files_and_overrides_keep_their_order() {
        let args = parse(&[
            "p",
            "--ros-args",
            "--params-file",
            "a.yaml",
            "-p",
            "x:=1",
            "--params-file",
            "b.yaml",
            "-p",
            "x:=2",
        ])
        .unwrap();
        let kinds: Vec<String> = args
            .param_sources
            .iter()
            .map(|s| match s {
                ParamSource::File(p) => p.display().to_string(),
                ParamSource::Override(o) => format!("{}={}", o.name, o.value),
            })
            .collect();
        assert_eq!(kinds, vec!["a.yaml", "x=1", "b.yaml", "x=2"]);
    }

    #[test]
    fn errors_name_the_bad_argument() {
        let err = parse(&["p", "--ros-args", "-r", "foo"]).unwrap_err();
        assert_eq!(err.to_string(), "-r expects [NODE:]FROM:=TO, got 'foo': no ':=' in it");
        let err = parse(&["p", "--ros-args", "--remap"]).unwrap_err();
        assert_eq!(err.to_string(), "--remap expects [NODE:]FROM:=TO, but nothing follows it");
        let err = parse(&["p", "--ros-args", "-p", "plate.side=1"]).unwrap_err();
        assert!(err.to_string().starts_with("-p expects [NODE:]NAME:=VALUE, got 'plate.side=1'"), "{err}");
        let err = parse(&["p", "--ros-args", "-p", "a:=[1, 2.5]"]).unwrap_err();
        assert!(err.to_string().contains("'a:=[1, 2.5]'") && err.to_string().contains("one type"), "{err}");
        let err = parse(&["p", "--ros-args", "--params-file"]).unwrap_err();
        assert!(matches!(err, ArgsError::MissingValue { ref flag, .. } if flag == "--params-file"));
        let err = parse(&["p", "--ros-args", "--log-level", "loud"]).unwrap_err();
        assert!(err.to_string().contains("unknown log level 'loud'"), "{err}");
        let err = parse(&["p", "--ros-args", "--verbose"]).unwrap_err();
        assert_eq!(err, ArgsError::UnknownRosArg("--verbose".into()));
        assert!(err.to_string().contains("'--verbose'"));
        // A flag's value is taken as is, even if it looks like a flag.
        let err = parse(&["p", "--ros-args", "-r", "--"]).unwrap_err();
        assert!(matches!(err, ArgsError::BadValue { ref got, .. } if got == "--"), "{err}");
        // Flags outside a block are the program's business.
        assert!(parse(&["p", "-r", "foo", "--verbose"]).is_ok());
    }

    #[test]
    fn remap_rule_parsing() {
        let r = RemapRule::parse("raw_scan:=/x").unwrap();
        assert_eq!(r, RemapRule { node: None, kind: RemapKind::Name, from: "raw_scan".into(), to: "/x".into() });
        let r = RemapRule::parse("tracer:raw_scan:=~/in").unwrap();
        assert_eq!((r.node.as_deref(), r.kind, r.to.as_str()), (Some("tracer"), RemapKind::Name, "~/in"));
        assert_eq!(RemapRule::parse("rostopic://a:=b").unwrap().kind, RemapKind::Topic);
        assert_eq!(RemapRule::parse("n:rosservice://a/b:=c").unwrap().kind, RemapKind::Service);
        assert_eq!(RemapRule::parse("__name:=x").unwrap().kind, RemapKind::NodeName);
        assert_eq!(RemapRule::parse("__ns:=/a/b/").unwrap().to, "/a/b");
        assert_eq!(RemapRule::parse("__ns:=/").unwrap().to, "/");
        for bad in [
            "foo",
            ":=x",
            "x:=",
            "__ns:=cell1",
            "__ns:=/1cell",
            "__node:=a/b",
            "__node:=9lives",
            "a b:=c",
            "a:=b c",
            "*:=x",
            "a/**:=x",
            "a:=\\1",
            "a//b:=c",
            "a:=b/",
            "bad-node:a:=b",
            "a:b:c:=d",
            "1a:=b",
        ] {
            assert!(RemapRule::parse(bad).is_err(), "{bad} should be rejected");
        }
    }

    #[test]
    fn param_override_parsing() {
        let o = ParamOverride::parse("calibration.alpha0:=0.0349").unwrap();
        assert_eq!(
            o,
            ParamOverride { node: None, name: "calibration.alpha0".into(), value: ParamValue::Double(0.0349) }
        );
        let o = ParamOverride::parse("tracer:resample_points:=0x10").unwrap();
        assert_eq!((o.node.as_deref(), o.value), (Some("tracer"), ParamValue::Integer(16)));
        let o = ParamOverride::parse("url:=a:=b").unwrap();
        assert_eq!(o.value, ParamValue::String("a:=b".into()));
        let o = ParamOverride::parse("output_frame_id:='1'").unwrap();
        assert_eq!(o.value, ParamValue::String("1".into()));
        for bad in ["x", "x=1", ":=1", "x:=", "a..b:=1", ".a:=1", "a-b:=1", "a/b:=1", "n-1:x:=1", "*:=1"] {
            assert!(ParamOverride::parse(bad).is_err(), "{bad} should be rejected");
        }
    }

    #[test]
    fn node_targeted_rules_apply_only_to_their_node() {
        let args = parse(&[
            "p",
            "--ros-args",
            "-r",
            "other:__node:=wrong",
            "-r",
            "tracer_calibrator:__ns:=/cell2",
            "-r",
            "other:raw_scan:=/not_mine",
            "-r",
            "tracer_calibrator:raw_scan:=/mine",
            "-p",
            "other:model:=paper",
            "-p",
            "tracer_calibrator:model:=full",
            "-p",
            "cell2/tracer_calibrator:model:=bad",
        ]);
        // a '/' is not allowed in a node prefix
        assert!(args.is_err());
        let args = parse(&[
            "p",
            "--ros-args",
            "-r",
            "other:__node:=wrong",
            "-r",
            "tracer_calibrator:__ns:=/cell2",
            "-r",
            "other:raw_scan:=/not_mine",
            "-r",
            "tracer_calibrator:raw_scan:=/mine",
            "-p",
            "other:model:=paper",
            "-p",
            "tracer_calibrator:model:=full",
        ])
        .unwrap();
        let node = args.node_identity("tracer_calibrator", "/").unwrap();
        assert_eq!(node.fully_qualified_name(), "/cell2/tracer_calibrator");
        assert_eq!(args.resolve_topic("raw_scan", &node).unwrap(), "/mine");
        let values: Vec<_> = args.param_overrides_for(&node).map(|o| o.value.clone()).collect();
        assert_eq!(values, vec![ParamValue::String("full".into())]);
    }

    #[test]
    fn the_first_matching_remap_wins() {
        let args = parse(&["p", "--ros-args", "-r", "__node:=a", "-r", "__node:=b", "-r", "x:=/one", "-r", "x:=/two"])
            .unwrap();
        let node = args.node_identity("d", "/").unwrap();
        assert_eq!(node.name, "a");
        assert_eq!(args.resolve_topic("x", &node).unwrap(), "/one");
    }

    #[test]
    fn topic_remaps_target_the_final_node_name() {
        // As in rcl: topic rules compare their NODE: prefix with the remapped node name.
        let args =
            parse(&["p", "--ros-args", "-r", "__node:=tracer", "-r", "tracer:x:=/y", "-r", "orig:x:=/z"]).unwrap();
        let node = args.node_identity("orig", "/").unwrap();
        assert_eq!(args.resolve_topic("x", &node).unwrap(), "/y");
    }

    // ------------------------------------------------------------ names

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

    // ------------------------------------------------------------ environment

    fn env(vars: &[(&str, &str)]) -> Result<RosEnv, EnvError> {
        let map: HashMap<String, String> = vars.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
        RosEnv::from_lookup(|k| map.get(k).cloned())
    }

    #[test]
    fn domain_id() {
        assert_eq!(parse_domain_id(None), Ok(0));
        assert_eq!(parse_domain_id(Some("")), Ok(0));
        assert_eq!(parse_domain_id(Some("0")), Ok(0));
        assert_eq!(parse_domain_id(Some("42")), Ok(42));
        assert_eq!(parse_domain_id(Some(" 7 ")), Ok(7));
        assert_eq!(parse_domain_id(Some("232")), Ok(232));
        assert_eq!(parse_domain_id(Some("0x10")), Ok(16));
        for bad in ["233", "-1", "+5", "abc", "12abc", "1.5", "99999999999999999999"] {
            assert_eq!(parse_domain_id(Some(bad)), Err(EnvError::DomainId(bad.into())), "{bad}");
        }
        assert_eq!(
            EnvError::DomainId("300".into()).to_string(),
            "ROS_DOMAIN_ID must be an integer in 0..=232, got '300'"
        );
    }

    #[test]
    fn discovery_range() {
        assert_eq!(parse_discovery_range(None), (DiscoveryRange::Subnet, None));
        assert_eq!(parse_discovery_range(Some("")), (DiscoveryRange::Subnet, None));
        assert_eq!(parse_discovery_range(Some("LOCALHOST")), (DiscoveryRange::Localhost, None));
        assert_eq!(parse_discovery_range(Some("SUBNET")), (DiscoveryRange::Subnet, None));
        assert_eq!(parse_discovery_range(Some("OFF")), (DiscoveryRange::Off, None));
        assert_eq!(parse_discovery_range(Some("SYSTEM_DEFAULT")), (DiscoveryRange::SystemDefault, None));
        let (range, warning) = parse_discovery_range(Some("localhost"));
        assert_eq!(range, DiscoveryRange::Localhost, "unknown values are the safe choice");
        assert!(warning.unwrap().contains("'localhost'"));
        assert!(DiscoveryRange::Localhost.is_local_only() && DiscoveryRange::Off.is_local_only());
        assert!(!DiscoveryRange::Subnet.is_local_only() && !DiscoveryRange::SystemDefault.is_local_only());
    }

    #[test]
    fn ros_env_from_values() {
        let e = env(&[]).unwrap();
        assert_eq!(
            e,
            RosEnv { domain_id: 0, discovery_range: DiscoveryRange::Subnet, static_peers: vec![], warnings: vec![] }
        );
        let e = env(&[
            ("ROS_DOMAIN_ID", "17"),
            ("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST"),
            ("ROS_STATIC_PEERS", "192.168.0.2; host.example;;"),
        ])
        .unwrap();
        assert_eq!(e.domain_id, 17);
        assert_eq!(e.discovery_range, DiscoveryRange::Localhost);
        assert_eq!(e.static_peers, vec!["192.168.0.2", "host.example"]);
        assert!(e.warnings.is_empty());
        let e = env(&[("ROS_LOCALHOST_ONLY", "1"), ("ROS_AUTOMATIC_DISCOVERY_RANGE", "SUBNET")]).unwrap();
        assert_eq!(e.discovery_range, DiscoveryRange::Localhost);
        assert_eq!(e.warnings.len(), 1);
        let e = env(&[("ROS_LOCALHOST_ONLY", "0")]).unwrap();
        assert_eq!(e.discovery_range, DiscoveryRange::Subnet);
        assert!(env(&[("ROS_DOMAIN_ID", "500")]).is_err());
        // the real environment reads without panicking
        let _ = RosEnv::from_env();
    }
}
