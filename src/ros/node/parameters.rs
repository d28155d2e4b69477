//! The node's ROS parameters: declared from the cell's [`Parameters`], validated by the same
//! rules as the params file, applied to the cell's state and persisted on a change; the
//! calibration `/calibrate` applies mirrored into them.

use log::{error, info};
use ros2_client::{NodeOptions, NumericRange, ParameterDescriptor, ParameterValue as RosValue};

use std::sync::{Mutex, OnceLock};

use super::{RosClock, Shared};
use crate::cell::NodeState;
use crate::params::spec::{Bound, Spec};
use crate::params::{ParamValue, Parameters, names, spec};
use crate::ros::qos_overrides::QosOverrides;

/// A ROS parameter value as ours; `None` for the kinds the node has no parameter of.
pub(super) fn from_ros(v: &RosValue) -> Option<ParamValue> {
    Some(match v {
        RosValue::Boolean(b) => ParamValue::Bool(*b),
        RosValue::Integer(i) => ParamValue::Integer(*i),
        RosValue::Double(d) => ParamValue::Double(*d),
        RosValue::String(s) => ParamValue::String(s.clone()),
        RosValue::BooleanArray(v) => ParamValue::BoolArray(v.clone()),
        RosValue::IntegerArray(v) => ParamValue::IntegerArray(v.clone()),
        RosValue::DoubleArray(v) => ParamValue::DoubleArray(v.clone()),
        RosValue::StringArray(v) => ParamValue::StringArray(v.clone()),
        RosValue::NotSet | RosValue::ByteArray(_) => return None,
    })
}

/// The descriptor a parameter is declared with, from its [`Spec`]: description, the range
/// rcl_interfaces can express, the rest as constraints, read-only.
pub(super) fn descriptor(spec: &Spec) -> ParameterDescriptor {
    let range = match spec.bound {
        Bound::Float { from, to } => NumericRange::FloatingPointRange { from_value: from, to_value: to, step: 0.0 },
        Bound::Integer { from, to } => NumericRange::IntegerRange { from_value: from, to_value: to, step: 0 },
        Bound::Any | Bound::Positive => NumericRange::NotSpecified,
    };
    let constraints = match (spec.bound, spec.constraints) {
        (Bound::Positive, "") => spec.bound_text(),
        (_, c) => c.to_string(),
    };
    ParameterDescriptor {
        name: spec.name.to_string(),
        param_type: ros2_client::parameters::ParameterType::NotSet, // the value's, when described
        description: spec.description.to_string(),
        additional_constraints: constraints,
        read_only: spec.read_only,
        dynamic_typing: false,
        range,
    }
}

/// A `qos_overrides.*` parameter's descriptor: read-only, as rclcpp declares them.
fn qos_descriptor(name: &str) -> ParameterDescriptor {
    ParameterDescriptor {
        name: name.to_string(),
        param_type: ros2_client::parameters::ParameterType::NotSet,
        description: "QoS override of an endpoint (rclcpp's qos_overrides), read at start-up".into(),
        additional_constraints: String::new(),
        read_only: true,
        dynamic_typing: false,
        range: NumericRange::NotSpecified,
    }
}

/// The node's options: rosout, every parameter declared with its descriptor (the
/// `qos_overrides.*` in force too), a validator and a set action over the shared state.
///
/// A change is validated by the same rules as the params file, applied to the state and
/// persisted, only when the value really changes (so the start-up round of set actions
/// writes nothing). A failed write fails the set. The read-only parameters
/// (`qos_overrides.*`, `managed`) are refused by ros2-client from their descriptors.
pub(super) fn options(params: &Parameters, qos: &QosOverrides, shared: &Shared) -> NodeOptions {
    let mut options = NodeOptions::new().enable_rosout(true);
    for (name, value) in params.to_list() {
        let spec = spec::spec(&name).expect("every parameter is declared in the spec");
        options = options.declare_parameter(&name, value.into()).describe_parameter(descriptor(spec));
    }
    for (name, value) in qos.to_list() {
        options = options.declare_parameter(&name, value.into()).describe_parameter(qos_descriptor(&name));
    }
    let validator_state = shared.state.clone();
    let action_state = shared.state.clone();
    let action_changed = shared.calibration_changed.clone();
    let action_clock = shared.clock.clone();
    options
        .parameter_validator(Box::new(move |name, value| validate(&validator_state, name, value)))
        .parameter_set_action(Box::new(move |name, value| {
            apply(&action_state, &action_changed, &action_clock, name, value)
        }))
}

/// The parameter validator: a change of one of the node's parameters checked by the same
/// rules as the params file (others, `qos_overrides.*`, pass: ros2-client refuses the
/// read-only ones from their descriptors).
pub(super) fn validate(state: &Mutex<NodeState>, name: &str, value: &RosValue) -> Result<(), String> {
    if !Parameters::is_known(name) {
        return Ok(());
    }
    let v = from_ros(value).ok_or_else(|| format!("{name}: unsupported value type"))?;
    let mut trial = state.lock().expect("state lock").params.clone();
    trial.set(name, &v).map_err(|e| format!("{name}: {e}"))
}

/// The parameter set action: a validated change applied to the cell's state and persisted,
/// only when the value really changes (so the start-up round of set actions writes
/// nothing); a failed write fails the set and leaves the value in force. A change of the
/// calibration in force is stamped on the node's clock and `changed` is told.
pub(super) fn apply(
    state: &Mutex<NodeState>,
    changed: &smol::channel::Sender<()>,
    clock: &OnceLock<RosClock>,
    name: &str,
    value: &RosValue,
) -> Result<(), String> {
    if !Parameters::is_known(name) {
        return Ok(());
    }
    let v = from_ros(value).ok_or_else(|| format!("{name}: unsupported value type"))?;
    let mut st = state.lock().expect("state lock");
    if st.params.get(name).as_ref() == Some(&v) {
        return Ok(());
    }
    let before = st.params.clone();
    st.params.set(name, &v).map_err(|e| format!("{name}: {e}"))?;
    if let Err(e) = st.persist() {
        st.params = before;
        return Err(format!("{name}: not changed: {e}"));
    }
    if names::CALIBRATION_IN_FORCE.contains(&name) {
        st.calibration_set_by_parameters(super::now_on(clock));
    }
    if name.starts_with("calibration.") || names::CALIBRATION_IN_FORCE.contains(&name) {
        let _ = changed.try_send(());
    }
    info!("parameter {name} = {v}");
    Ok(())
}

/// Tell the ROS parameter server the parameters a calibration `/calibrate` applied set (the
/// cell owns them, validated and persisted: the set action sees equal values and writes
/// nothing), as one change: one `/parameter_events` message, as a calibration is one event.
pub(super) fn mirror_calibration(e: &impl super::Wire, set: &[(&'static str, ParamValue)]) {
    let params =
        set.iter().map(|(name, value)| ros2_client::Parameter { name: name.to_string(), value: value.clone().into() });
    if let Err(err) = e.set_parameters(params.collect()) {
        error!("cannot mirror the calibration into the ROS parameters: {err}");
    }
}
