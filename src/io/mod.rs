//! Files the tools read and write: scans as CSV (and, with the bag issue, rosbag2).

pub mod bag;
pub mod csv;
pub mod oma;
pub mod plot;
