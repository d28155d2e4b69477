//! The node's ROS parameters: declared from the cell's [`Parameters`], validated by the same
//! rules as the params file, applied to the cell's state and persisted on a change; the
//! calibration `/calibrate` applies mirrored into them.

use log::{error, info};
use ros2_client::{NodeOptions, ParameterValue as RosValue};

use super::Shared;
use crate::engine::geometry::Mounting;
use crate::params::{ParamValue, Parameters, names};
use crate::ros::qos_overrides::{self, QosOverrides};

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

/// The node's options: rosout, every parameter declared (the `qos_overrides.*` in force
/// too), a validator and a set action over the shared state.
///
/// A change is validated by the same rules as the params file, applied to the state and
/// persisted, only when the value really changes (so the start-up round of set actions
/// writes nothing). A failed write fails the set. `qos_overrides.*` are read-only, as
/// rclcpp declares them: only the value given at start passes.
pub(super) fn options(params: &Parameters, qos: &QosOverrides, shared: &Shared) -> NodeOptions {
    let mut options = NodeOptions::new().enable_rosout(true);
    for (name, value) in params.to_list().into_iter().chain(qos.to_list()) {
        options = options.declare_parameter(&name, value.into());
    }
    let validator_state = shared.state.clone();
    let validator_qos = qos.clone();
    let action_state = shared.state.clone();
    let action_changed = shared.calibration_changed.clone();
    options
        .parameter_validator(Box::new(move |name, value| {
            if qos_overrides::is_override(name) {
                return match (from_ros(value), validator_qos.get(name)) {
                    (Some(v), Some(given)) if &v == given => Ok(()),
                    _ => Err(format!("{name} is read-only: QoS overrides are read at start-up only")),
                };
            }
            if !Parameters::is_known(name) {
                return Ok(());
            }
            let v = from_ros(value).ok_or_else(|| format!("{name}: unsupported value type"))?;
            let mut trial = validator_state.lock().expect("state lock").params.clone();
            trial.set(name, &v).map_err(|e| format!("{name}: {e}"))
        }))
        .parameter_set_action(Box::new(move |name, value| {
            if !Parameters::is_known(name) {
                return Ok(());
            }
            let v = from_ros(value).ok_or_else(|| format!("{name}: unsupported value type"))?;
            let mut st = action_state.lock().expect("state lock");
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
                st.calibration_set_by_parameters(std::time::SystemTime::now());
            }
            if name.starts_with("calibration.") {
                let _ = action_changed.try_send(());
            }
            info!("parameter {name} = {v}");
            Ok(())
        }))
}

/// Mirror a calibration `/calibrate` applied into the ROS parameters (already persisted:
/// the set action sees equal values and writes nothing).
pub(super) fn mirror_calibration(node: &ros2_client::Node, m: &Mounting) {
    for (name, value) in [
        (names::ALPHA0, RosValue::Double(m.alpha0)),
        (names::OFFSET, RosValue::Double(m.offset)),
        (names::DELTA_L, RosValue::Double(m.delta_l)),
        (names::SCALE, RosValue::Double(m.scale)),
        (names::VALID, RosValue::Boolean(true)),
    ] {
        if let Err(e) = node.set_parameter(name, value) {
            error!("cannot mirror {name} into the ROS parameters: {e}");
        }
    }
}
