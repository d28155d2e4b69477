//! ROS 2 command-line arguments and parameter value typing: what `rcl` does for a C++ or
//! Python node, and ros2-client does not. Names and their resolution: [`crate::names`]; the
//! ROS environment variables: [`crate::rmw::env`].
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
//! | `-p`/`--param [NODE:]NAME:=VALUE` | parameter override; `NAME` as rcl reads it (parts of tokens and `/` separated by `.`: `qos_overrides./raw_scan.subscription.depth`), `VALUE` a one-line YAML value, typed like a params file ([`ParamValue::parse_yaml`]); a value rcl reads as NOT_SET (`[]`, a comment alone) sets nothing |
//! | `--params-file FILE` | parameters file; may repeat |
//! | `--log-level LEVEL` / `--log-level LOGGER:=LEVEL` | `debug info warn error fatal unset`, any case: the node logger's level, by rcl's rules ([`crate::ros::logging`]) |
//! | `--log-config-file FILE`, `-e`/`--enclave NAME`, `--log-file-name NAME` | recorded |
//! | `--enable-`/`--disable-` + `stdout-logs`/`rosout-logs` | the node's records on stderr / on `/rosout` |
//! | `--enable-`/`--disable-external-lib-logs` | accepted, ignored |
//!
//! Anything else inside a block is an error, as in rclcpp ("unknown ROS arguments"); so is a
//! flag with nothing after it, or a malformed rule. Errors name the flag and the argument.
//!
//! Order matters as in rcl: among several rules for the same thing the **first** matching
//! remap wins, and parameter files and `-p` overrides are applied in command-line order, the
//! later ones winning ([`RosArgs::param_sources`] keeps that order).
//!
//! # Parameter values
//!
//! [`ParamValue::from_yaml_scalar`] types a YAML scalar exactly as `rcl_yaml_param_parser`
//! does: quoted -> string; else YAML 1.1 booleans; else a C `strtoll(.., 0)` integer (so `0x1f`
//! is 31 and `010` is 8!); else a C `strtod` double (also `.inf`, `-.inf`, `.nan`, `nan`,
//! `inf`, `1e3`, hex floats); else a string.
//!

use std::path::{Path, PathBuf};
use std::str::FromStr;

pub use crate::params::ParamValue;

use crate::names::{
    NameError, NodeIdentity, normalize_namespace, resolve_service, resolve_topic, validate_namespace,
    validate_node_name,
};

mod rules;
#[cfg(test)]
mod tests;

pub use crate::names::{RemapKind, RemapRule};
pub use rules::{ParamOverride, ParamSource};

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

/// A `--log-level` value that names no level ([`LogLevel`]'s `FromStr`).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown log level '{0}' (debug, info, warn, error, fatal, unset)")]
pub struct UnknownLogLevel(pub String);

impl FromStr for LogLevel {
    type Err = UnknownLogLevel;

    /// Case-insensitive `debug`, `info`, `warn`/`warning`, `error`, `fatal`, `unset`.
    fn from_str(s: &str) -> Result<Self, UnknownLogLevel> {
        Ok(match s.to_ascii_lowercase().as_str() {
            "unset" => LogLevel::Unset,
            "debug" => LogLevel::Debug,
            "info" => LogLevel::Info,
            "warn" | "warning" => LogLevel::Warn,
            "error" => LogLevel::Error,
            "fatal" => LogLevel::Fatal,
            _ => return Err(UnknownLogLevel(s.to_string())),
        })
    }
}

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
    /// `--enable-stdout-logs` / `--disable-stdout-logs` (the last one given): the node's
    /// records on stderr ([`crate::ros::logging`]).
    pub stdout_logs: Option<bool>,
    /// `--enable-rosout-logs` / `--disable-rosout-logs` (the last one given): the node's
    /// records on `/rosout`.
    pub rosout_logs: Option<bool>,
    /// ROS arguments that were accepted but have no effect here (`--disable-external-lib-logs`,
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
                    match ParamOverride::parse(&v) {
                        Ok(o) => out.param_sources.push(ParamSource::Override(o)),
                        Err(_) if ParamOverride::is_not_set(&v) => out.ignored.push(format!("{arg} {v}")),
                        Err(e) => return Err(bad(EXPECT_PARAM, &v, e)),
                    }
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
                    let (logger, level) = match v.split_once(":=") {
                        Some((logger, level)) => (Some(logger), level),
                        None => (None, v.as_str()),
                    };
                    if logger == Some("") {
                        return Err(bad(EXPECT_LOG_LEVEL, &v, "empty logger name".into()));
                    }
                    let level = level.parse().map_err(|e: UnknownLogLevel| bad(EXPECT_LOG_LEVEL, &v, e.to_string()))?;
                    match logger {
                        Some(logger) => out.logger_levels.push((logger.to_string(), level)),
                        None => out.log_level = Some(level),
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
                "--enable-stdout-logs" | "--disable-stdout-logs" => {
                    out.stdout_logs = Some(arg.starts_with("--enable"));
                }
                "--enable-rosout-logs" | "--disable-rosout-logs" => {
                    out.rosout_logs = Some(arg.starts_with("--enable"));
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
