//! `-r [NODE:]FROM:=TO` remap rules, as rcl parses them (matching them: [`super::resolve_topic`]).

use super::{is_token, normalize_namespace, validate_namespace, validate_node_name};

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

    pub(crate) fn applies_to_kind(&self, service: bool) -> bool {
        match self.kind {
            RemapKind::Name => true,
            RemapKind::Topic => !service,
            RemapKind::Service => service,
            RemapKind::NodeName | RemapKind::Namespace => false,
        }
    }
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
