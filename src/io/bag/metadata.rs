//! `metadata.yaml`, the description rosbag2 keeps next to the storage files of a bag.
//!
//! ```yaml
//! rosbag2_bagfile_information:
//!   version: 9
//!   storage_identifier: mcap            # or sqlite3
//!   relative_file_paths: [scans_0.mcap] # split bags list several
//!   duration: {nanoseconds: 2000000000}
//!   starting_time: {nanoseconds_since_epoch: 1700000000000000000}
//!   message_count: 3
//!   topics_with_message_count:
//!     - topic_metadata: {name: /raw_scan, type: tracer_calib_msgs/msg/RawScan,
//!                        serialization_format: cdr, offered_qos_profiles: [...],
//!                        type_description_hash: ''}
//!       message_count: 3
//!   compression_format: ''              # zstd when compressed
//!   compression_mode: ''                # FILE or MESSAGE when compressed
//!   files: [...]                        # per file: path, starting_time, duration, message_count
//!   custom_data: {}
//!   ros_distro: ''
//! ```
//!
//! Up to version 8 `offered_qos_profiles` is a YAML *string* holding a list with enums as
//! numbers; version 9 makes it a YAML list with enums as names. Reading needs only the storage
//! identifier, the file list and the compression settings: the topics come from the storage
//! files themselves.

use std::path::{Path, PathBuf};

use yaml_rust2::yaml::{Array, Hash};
use yaml_rust2::{Yaml, YamlEmitter, YamlLoader};

use super::{BagError, StorageFormat};

/// The QoS profile written for every topic, in the form of rosbag2 version 9 (the MCAP channel
/// metadata `offered_qos_profiles`, and parsed, the list in `metadata.yaml`): reliable, volatile,
/// keep last 10, automatic liveliness, infinite durations (rosbag2 writes `i64::MAX` ns).
pub const OFFERED_QOS_PROFILES: &str = "\
- history: keep_last
  depth: 10
  reliability: reliable
  durability: volatile
  deadline:
    sec: 9223372036
    nsec: 854775807
  lifespan:
    sec: 9223372036
    nsec: 854775807
  liveliness: automatic
  liveliness_lease_duration:
    sec: 9223372036
    nsec: 854775807
  avoid_ros_namespace_conventions: false";

/// The rosbag2 metadata version the writer produces.
pub const VERSION: i64 = 9;

/// What the reader takes from `metadata.yaml`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct BagMetadata {
    pub format: StorageFormat,
    /// The storage files, resolved against the bag directory.
    pub files: Vec<PathBuf>,
}

/// Reads `dir/metadata.yaml`.
pub(crate) fn read(dir: &Path) -> Result<BagMetadata, BagError> {
    let path = dir.join("metadata.yaml");
    let text = std::fs::read_to_string(&path).map_err(|source| BagError::Io { path: path.clone(), source })?;
    let bad = |reason: String| BagError::Metadata { path: path.clone(), reason };
    let docs = YamlLoader::load_from_str(&text).map_err(|e| bad(format!("not YAML: {e}")))?;
    let info = docs.first().map(|d| &d["rosbag2_bagfile_information"]).unwrap_or(&Yaml::BadValue);
    if info.is_badvalue() {
        return Err(bad("no rosbag2_bagfile_information".into()));
    }
    let storage = info["storage_identifier"].as_str().ok_or_else(|| bad("no storage_identifier".into()))?;
    let format = match storage {
        "mcap" => StorageFormat::Mcap,
        "sqlite3" => StorageFormat::Sqlite3,
        other => {
            return Err(BagError::Unsupported {
                path: path.clone(),
                reason: format!("storage_identifier {other:?} (only mcap and sqlite3 are supported)"),
            });
        }
    };
    let mode = info["compression_mode"].as_str().unwrap_or("");
    if !mode.is_empty() && !mode.eq_ignore_ascii_case("none") {
        let fmt = info["compression_format"].as_str().unwrap_or("");
        return Err(BagError::Unsupported {
            path: path.clone(),
            reason: format!(
                "compressed bag (compression_mode {mode}, compression_format {fmt}); decompress it first, e.g. with `ros2 bag convert`"
            ),
        });
    }
    let list = info["relative_file_paths"].as_vec().ok_or_else(|| bad("no relative_file_paths".into()))?;
    if list.is_empty() {
        return Err(bad("relative_file_paths is empty".into()));
    }
    let mut files = Vec::with_capacity(list.len());
    for entry in list {
        let rel = entry.as_str().ok_or_else(|| bad("relative_file_paths holds a non-string".into()))?;
        // Before version 4 the paths included the bag directory's own name; rosbag2 and rosbags
        // fall back to the file name, and so does this.
        let direct = dir.join(rel);
        let file = if direct.is_file() {
            direct
        } else {
            match Path::new(rel).file_name().map(|name| dir.join(name)) {
                Some(by_name) if by_name.is_file() => by_name,
                _ => return Err(bad(format!("lists storage file {rel}, which does not exist"))),
            }
        };
        files.push(file);
    }
    Ok(BagMetadata { format, files })
}

/// One topic for [`write`].
pub(crate) struct TopicEntry<'a> {
    pub name: &'a str,
    pub type_name: &'a str,
    pub count: u64,
}

/// What [`write`] describes: one MCAP storage file.
pub(crate) struct Summary<'a> {
    pub file_name: &'a str,
    /// `(first, last)` log time, ns; `None` without messages.
    pub time_range: Option<(u64, u64)>,
    pub topics: Vec<TopicEntry<'a>>,
}

fn hash(entries: Vec<(&str, Yaml)>) -> Yaml {
    let mut h = Hash::new();
    for (k, v) in entries {
        h.insert(Yaml::String(k.to_string()), v);
    }
    Yaml::Hash(h)
}

fn int(v: u64) -> Yaml {
    Yaml::Integer(i64::try_from(v).unwrap_or(i64::MAX))
}

fn string(s: &str) -> Yaml {
    Yaml::String(s.to_string())
}

/// The `rosbag2_bagfile_information` mapping (without that key) for `summary`.
pub(crate) fn bagfile_information(summary: &Summary) -> Yaml {
    let (start, duration) = summary.time_range.map(|(a, b)| (a, b - a)).unwrap_or((0, 0));
    let count: u64 = summary.topics.iter().map(|t| t.count).sum();
    let qos = YamlLoader::load_from_str(OFFERED_QOS_PROFILES)
        .ok()
        .and_then(|mut d| d.pop())
        .unwrap_or_else(|| Yaml::Array(Array::new()));
    let topics = summary
        .topics
        .iter()
        .map(|t| {
            hash(vec![
                (
                    "topic_metadata",
                    hash(vec![
                        ("name", string(t.name)),
                        ("type", string(t.type_name)),
                        ("serialization_format", string("cdr")),
                        ("offered_qos_profiles", qos.clone()),
                        ("type_description_hash", string("")),
                    ]),
                ),
                ("message_count", int(t.count)),
            ])
        })
        .collect();
    let duration_yaml = || hash(vec![("nanoseconds", int(duration))]);
    let start_yaml = || hash(vec![("nanoseconds_since_epoch", int(start))]);
    hash(vec![
        ("version", Yaml::Integer(VERSION)),
        ("storage_identifier", string("mcap")),
        ("duration", duration_yaml()),
        ("starting_time", start_yaml()),
        ("message_count", int(count)),
        ("topics_with_message_count", Yaml::Array(topics)),
        ("compression_format", string("")),
        ("compression_mode", string("")),
        ("relative_file_paths", Yaml::Array(vec![string(summary.file_name)])),
        (
            "files",
            Yaml::Array(vec![hash(vec![
                ("path", string(summary.file_name)),
                ("starting_time", start_yaml()),
                ("duration", duration_yaml()),
                ("message_count", int(count)),
            ])]),
        ),
        ("custom_data", Yaml::Hash(Hash::new())),
        ("ros_distro", string("")),
    ])
}

/// YAML text of `doc`, without the leading `---` line.
pub(crate) fn to_text(doc: &Yaml) -> String {
    let mut out = String::new();
    // Emitting into a String cannot fail.
    let _ = YamlEmitter::new(&mut out).dump(doc);
    let body = out.strip_prefix("---\n").unwrap_or(&out);
    format!("{body}\n")
}

/// The text of `metadata.yaml` for `summary`.
pub(crate) fn metadata_yaml(summary: &Summary) -> String {
    to_text(&hash(vec![("rosbag2_bagfile_information", bagfile_information(summary))]))
}
