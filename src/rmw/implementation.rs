//! `RMW_IMPLEMENTATION`: which middleware the process joins, read as a stock node's rmw
//! loader reads it (rmw_implementation: unset or empty means the default).
//!
//! | value | middleware |
//! |---|---|
//! | unset, empty, `rmw_fastrtps_cpp`, `rmw_cyclonedds_cpp` | DDS ([`super::dds`]), as before |
//! | `rmw_zenoh_cpp` | Zenoh, rmw_zenoh's protocol ([`super::zenoh`]) |
//! | anything else | an error naming the value and the two middlewares |
//!
//! A Fast DDS or Cyclone DDS peer is reached by the same DDS participant (the node reads
//! each vendor's service layout, `vendor/ros2-client/PATCHES.md`), so both names mean DDS.

/// The middleware a process joins.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Middleware {
    /// DDS (RTPS), the ROS 2 default: what rmw_fastrtps_cpp and rmw_cyclonedds_cpp speak.
    Dds,
    /// rmw_zenoh_cpp's protocol over a Zenoh session (usually through the cell's router).
    Zenoh,
}

/// The DDS implementations whose peers the node's DDS participant serves.
pub const DDS_IMPLEMENTATIONS: [&str; 2] = ["rmw_fastrtps_cpp", "rmw_cyclonedds_cpp"];
/// The Zenoh implementation.
pub const ZENOH_IMPLEMENTATION: &str = "rmw_zenoh_cpp";

/// An `RMW_IMPLEMENTATION` the node does not speak.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "RMW_IMPLEMENTATION '{0}' is not supported: this node speaks DDS (rmw_fastrtps_cpp, \
     rmw_cyclonedds_cpp, or unset) and Zenoh (rmw_zenoh_cpp)"
)]
pub struct UnknownImplementation(pub String);

impl Middleware {
    /// The middleware `RMW_IMPLEMENTATION` (`value`) names; surrounding whitespace
    /// ignored, as the names are matched exactly otherwise.
    pub fn from_rmw_implementation(value: Option<&str>) -> Result<Middleware, UnknownImplementation> {
        match value.map(str::trim).unwrap_or("") {
            "" => Ok(Middleware::Dds),
            v if DDS_IMPLEMENTATIONS.contains(&v) => Ok(Middleware::Dds),
            ZENOH_IMPLEMENTATION => Ok(Middleware::Zenoh),
            other => Err(UnknownImplementation(other.to_string())),
        }
    }

    /// `RMW_IMPLEMENTATION` of the process environment.
    pub fn from_env() -> Result<Middleware, UnknownImplementation> {
        let value = std::env::var_os("RMW_IMPLEMENTATION").map(|v| v.to_string_lossy().into_owned());
        Middleware::from_rmw_implementation(value.as_deref())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_as_the_rmw_loader() {
        for dds in [None, Some(""), Some("rmw_fastrtps_cpp"), Some("rmw_cyclonedds_cpp"), Some(" rmw_fastrtps_cpp ")] {
            assert_eq!(Middleware::from_rmw_implementation(dds), Ok(Middleware::Dds), "{dds:?}");
        }
        assert_eq!(Middleware::from_rmw_implementation(Some("rmw_zenoh_cpp")), Ok(Middleware::Zenoh));
        let err = Middleware::from_rmw_implementation(Some("rmw_connextdds")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "RMW_IMPLEMENTATION 'rmw_connextdds' is not supported: this node speaks DDS (rmw_fastrtps_cpp, \
             rmw_cyclonedds_cpp, or unset) and Zenoh (rmw_zenoh_cpp)"
        );
        assert!(Middleware::from_rmw_implementation(Some("RMW_ZENOH_CPP")).is_err(), "exact names");
    }
}
