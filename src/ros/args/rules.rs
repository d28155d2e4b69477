//! `-r` remap rules and `-p` parameter overrides, as rcl parses and matches them.

use std::path::PathBuf;

use super::ParamValue;
use crate::names::{NodeIdentity, is_token};

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
        if lhs.starts_with("rostopic://") || lhs.starts_with("rosservice://") {
            return Err(format!("'{lhs}': a remap's URL scheme is no parameter name"));
        }
        let (node, name) = match lhs.split_once(':') {
            Some((node, name)) => {
                if !is_token(node) {
                    return Err(format!("'{node}' before ':' is not a node name"));
                }
                (Some(node.to_string()), name)
            }
            None => (None, lhs),
        };
        check_param_name(name)?;
        let value = ParamValue::parse_yaml(value).map_err(|e| e.to_string())?;
        Ok(ParamOverride { node, name: name.to_string(), value })
    }

    /// Whether `rule` is a well-formed override whose value rcl reads as NOT_SET (a comment
    /// alone, `x:=#...`, or an empty sequence, `x:=[]`): rcl takes it, and it sets nothing.
    pub fn is_not_set(rule: &str) -> bool {
        let Some((lhs, value)) = rule.split_once(":=") else { return false };
        let name = lhs.split_once(':').map_or(lhs, |(_, name)| name);
        let value = value.trim_start();
        let empty_sequence =
            value.strip_prefix('[').map(str::trim_start).and_then(|v| v.strip_prefix(']')).is_some_and(|rest| {
                let rest = rest.trim_start();
                rest.is_empty() || rest.starts_with('#')
            });
        check_param_name(name).is_ok() && (value.starts_with('#') || empty_sequence)
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

/// A parameter name as rcl's `-p` rule reads it (`_rcl_parse_param_name`): parts separated by
/// `.`, each a run of name tokens and `/` (as in `qos_overrides./raw_scan.subscription.depth`);
/// a token, as rcl's lexer makes them, does not start with a digit or with `__` (`__ns`,
/// `__node` are other lexemes).
fn check_param_name(name: &str) -> Result<(), String> {
    let fail = |why: &str| Err(format!("'{name}' is not a parameter name: {why}"));
    for part in name.split('.') {
        if part.is_empty() {
            return fail("parts of [A-Za-z0-9_/] separated by '.', none empty");
        }
        for token in part.split('/').filter(|t| !t.is_empty()) {
            if !is_token(token) {
                return fail("parts of [A-Za-z0-9_/] separated by '.'");
            }
            if token.starts_with(|c: char| c.is_ascii_digit()) {
                return fail("a name token must not start with a digit");
            }
            if token.starts_with("__") {
                return fail("a name token must not start with '__'");
            }
        }
    }
    Ok(())
}

/// A source of parameter values, in command-line order.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamSource {
    /// `--params-file FILE`.
    File(PathBuf),
    /// `-p NAME:=VALUE`.
    Override(ParamOverride),
}
