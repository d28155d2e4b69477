//! QoS overrides, as rclcpp offers them (`rclcpp::QosOverridingOptions`): parameters
//! `qos_overrides.<topic>.<publisher|subscription>.<policy>`, where `<topic>` is the fully
//! qualified topic name (after namespace and remaps, e.g. `/cell1/raw_scan`) and
//! `<policy>` one of
//!
//! | policy | values |
//! |---|---|
//! | `reliability` | `reliable`, `best_effort`, `system_default` |
//! | `durability` | `volatile`, `transient_local`, `system_default` |
//! | `history` | `keep_last`, `keep_all`, `system_default` |
//! | `depth` | integer >= 1 (the keep-last depth) |
//!
//! `system_default` keeps the node's own choice. They are read at start-up, from a
//! params file or `-p`, for the node's `raw_scan` subscription and its `contour` and
//! `contour_polygon` publishers; afterwards they are read-only ROS parameters (a set is
//! refused). A bad value stops the node with a message naming the parameter; an override
//! for a topic the node has no such endpoint on gives one warning and is ignored. The
//! overrides in force are written back with the other parameters when the node persists.

use ros2_client::{
    QosProfile,
    qos::{Durability, History, Reliability, WhenFull},
};

use crate::params::ParamValue;

/// The parameter name prefix.
pub const PREFIX: &str = "qos_overrides.";

/// Which side of a topic an override is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    Publisher,
    Subscription,
}

impl Side {
    fn as_str(self) -> &'static str {
        match self {
            Side::Publisher => "publisher",
            Side::Subscription => "subscription",
        }
    }
}

/// One override, parsed and checked.
#[derive(Debug, Clone, PartialEq)]
pub struct Override {
    pub topic: String,
    pub side: Side,
    pub policy: Policy,
}

/// A policy value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Policy {
    Reliability(Option<bool>), // Some(true) = reliable; None = system_default
    Durability(Option<bool>),  // Some(true) = transient_local
    History(Option<bool>),     // Some(true) = keep_all
    Depth(usize),
}

/// Is `name` a QoS override parameter?
pub fn is_override(name: &str) -> bool {
    name.starts_with(PREFIX)
}

/// Parse and check one `qos_overrides.*` parameter.
pub fn parse(name: &str, value: &ParamValue) -> Result<Override, String> {
    let rest = name.strip_prefix(PREFIX).ok_or_else(|| format!("{name}: not a QoS override"))?;
    let mut parts = rest.rsplitn(3, '.');
    let (policy, side, topic) = (parts.next(), parts.next(), parts.next());
    let (Some(policy), Some(side), Some(topic)) = (policy, side, topic) else {
        return Err(format!("{name}: expected qos_overrides.<topic>.<publisher|subscription>.<policy>"));
    };
    let side = match side {
        "publisher" => Side::Publisher,
        "subscription" => Side::Subscription,
        other => return Err(format!("{name}: '{other}' is neither 'publisher' nor 'subscription'")),
    };
    if !topic.starts_with('/') {
        return Err(format!("{name}: the topic must be fully qualified (e.g. '/{topic}')"));
    }
    let text = |allowed: &[&str]| -> Result<String, String> {
        match value {
            ParamValue::String(s) if allowed.contains(&s.as_str()) => Ok(s.clone()),
            other => Err(format!("{name}: expected one of {}, got '{other}'", allowed.join(", "))),
        }
    };
    let policy = match policy {
        "reliability" => Policy::Reliability(match text(&["reliable", "best_effort", "system_default"])?.as_str() {
            "reliable" => Some(true),
            "best_effort" => Some(false),
            _ => None,
        }),
        "durability" => Policy::Durability(match text(&["volatile", "transient_local", "system_default"])?.as_str() {
            "transient_local" => Some(true),
            "volatile" => Some(false),
            _ => None,
        }),
        "history" => Policy::History(match text(&["keep_last", "keep_all", "system_default"])?.as_str() {
            "keep_all" => Some(true),
            "keep_last" => Some(false),
            _ => None,
        }),
        "depth" => match value {
            ParamValue::Integer(d) if *d >= 1 && *d <= 1_000_000 => Policy::Depth(*d as usize),
            other => return Err(format!("{name}: expected an integer 1..1000000, got '{other}'")),
        },
        other => {
            return Err(format!(
                "{name}: '{other}' cannot be overridden (reliability, durability, history, depth can)"
            ));
        }
    };
    Ok(Override { topic: topic.to_string(), side, policy })
}

/// The overrides given at start-up, in the order given (later ones win).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct QosOverrides {
    entries: Vec<(String, ParamValue, Override)>,
}

impl QosOverrides {
    /// Add (or replace) one; the error names the parameter.
    pub fn set(&mut self, name: &str, value: &ParamValue) -> Result<(), String> {
        let o = parse(name, value)?;
        self.entries.retain(|(n, _, _)| n != name);
        self.entries.push((name.to_string(), value.clone(), o));
        Ok(())
    }

    /// `base` with the overrides for `topic`'s `side` applied.
    pub fn apply(&self, topic: &str, side: Side, base: QosProfile) -> QosProfile {
        let mut q = base;
        for (_, _, o) in self.entries.iter().filter(|(_, _, o)| o.topic == topic && o.side == side) {
            match o.policy {
                Policy::Reliability(Some(true)) => q = q.reliability_reliable(WhenFull::DEFAULT),
                Policy::Reliability(Some(false)) => q = q.reliability(Reliability::BestEffort),
                Policy::Durability(Some(true)) => q = q.durability(Durability::TransientLocal),
                Policy::Durability(Some(false)) => q = q.durability(Durability::Volatile),
                Policy::History(Some(true)) => q = q.history(History::KeepAll),
                Policy::History(Some(false)) => {
                    if q.history == History::KeepAll {
                        q = q.history(History::KeepLast { depth: 10 });
                    }
                }
                Policy::Depth(depth) => {
                    if let History::KeepLast { .. } = q.history {
                        q = q.history(History::KeepLast { depth });
                    }
                }
                Policy::Reliability(None) | Policy::Durability(None) | Policy::History(None) => {}
            }
        }
        // A depth given before a keep_last that came after keep_all: apply it again.
        if let History::KeepLast { .. } = q.history
            && let Some(depth) = self.entries.iter().rev().find_map(|(_, _, o)| match o.policy {
                Policy::Depth(d) if o.topic == topic && o.side == side => Some(d),
                _ => None,
            })
        {
            q = q.history(History::KeepLast { depth });
        }
        q
    }

    /// The overrides that are not for one of `endpoints` (topic, side): each one line
    /// for a warning.
    pub fn unused(&self, endpoints: &[(&str, Side)]) -> Vec<String> {
        self.entries
            .iter()
            .filter(|(_, _, o)| !endpoints.iter().any(|(t, s)| *t == o.topic && *s == o.side))
            .map(|(n, _, o)| {
                format!("{n}: this node has no {} on {}, ignored (names are fully qualified)", o.side.as_str(), o.topic)
            })
            .collect()
    }

    /// Keep only the overrides for `endpoints`.
    pub fn retain_for(&mut self, endpoints: &[(&str, Side)]) {
        self.entries.retain(|(_, _, o)| endpoints.iter().any(|(t, s)| *t == o.topic && *s == o.side));
    }

    /// Name and value of each override in force (declared as read-only parameters, persisted).
    pub fn to_list(&self) -> Vec<(String, ParamValue)> {
        self.entries.iter().map(|(n, v, _)| (n.clone(), v.clone())).collect()
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// The value given for `name`, if any.
    pub fn get(&self, name: &str) -> Option<&ParamValue> {
        self.entries.iter().find(|(n, _, _)| n == name).map(|(_, v, _)| v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(v: &str) -> ParamValue {
        ParamValue::String(v.to_string())
    }

    #[test]
    fn names_and_values_as_rclcpp() {
        let o = parse("qos_overrides./raw_scan.subscription.reliability", &s("best_effort")).unwrap();
        assert_eq!(
            o,
            Override { topic: "/raw_scan".into(), side: Side::Subscription, policy: Policy::Reliability(Some(false)) }
        );
        let o = parse("qos_overrides./cell1/contour.publisher.depth", &ParamValue::Integer(50)).unwrap();
        assert_eq!((o.topic.as_str(), o.side, o.policy), ("/cell1/contour", Side::Publisher, Policy::Depth(50)));
        for (name, value, what) in [
            ("qos_overrides./raw_scan.subscription.reliability", s("fast"), "expected one of reliable"),
            ("qos_overrides./raw_scan.subscription.depth", ParamValue::Integer(0), "1..1000000"),
            ("qos_overrides./raw_scan.subscription.depth", s("10"), "expected an integer"),
            ("qos_overrides./raw_scan.reader.reliability", s("reliable"), "neither 'publisher'"),
            ("qos_overrides.raw_scan.subscription.reliability", s("reliable"), "fully qualified"),
            ("qos_overrides./raw_scan.subscription.deadline", s("1"), "cannot be overridden"),
            ("qos_overrides.reliability", s("reliable"), "expected qos_overrides.<topic>"),
        ] {
            let e = parse(name, &value).unwrap_err();
            assert!(e.starts_with(name) && e.contains(what), "{name}: {e}");
        }
    }

    #[test]
    fn applied_to_the_profile_of_its_topic_and_side_only() {
        let base = QosProfile::publisher_default()
            .reliability_reliable(WhenFull::DEFAULT)
            .durability(Durability::Volatile)
            .history(History::KeepLast { depth: 100 });
        let mut o = QosOverrides::default();
        o.set("qos_overrides./raw_scan.subscription.reliability", &s("best_effort")).unwrap();
        o.set("qos_overrides./raw_scan.subscription.depth", &ParamValue::Integer(5)).unwrap();
        o.set("qos_overrides./contour.publisher.durability", &s("transient_local")).unwrap();
        let q = o.apply("/raw_scan", Side::Subscription, base.clone());
        assert_eq!(q.reliability, Reliability::BestEffort);
        assert_eq!(q.history, History::KeepLast { depth: 5 });
        assert_eq!(q.durability, Durability::Volatile);
        assert_eq!(o.apply("/raw_scan", Side::Publisher, base.clone()), base);
        assert_eq!(o.apply("/contour", Side::Publisher, base.clone()).durability, Durability::TransientLocal);
        o.set("qos_overrides./raw_scan.subscription.reliability", &s("system_default")).unwrap();
        assert!(matches!(
            o.apply("/raw_scan", Side::Subscription, base.clone()).reliability,
            Reliability::Reliable { .. }
        ));
        let unused = o.unused(&[("/raw_scan", Side::Subscription)]);
        assert_eq!(unused.len(), 1);
        assert!(unused[0].contains("no publisher on /contour"), "{unused:?}");
        o.retain_for(&[("/raw_scan", Side::Subscription)]);
        assert_eq!(o.to_list().len(), 2);
    }
}
