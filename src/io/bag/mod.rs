//! rosbag2 bags: reading MCAP and sqlite3 bags, writing MCAP bags.
//!
//! # What a bag is
//!
//! `ros2 bag record` writes a *bag directory*: a `metadata.yaml` (see [`metadata`]) naming the
//! storage plugin (`storage_identifier: mcap` or `sqlite3`) and the storage files
//! (`relative_file_paths`, several when the bag was split), plus those files. Each storage file
//! holds, per topic, its name, its type (`pkg/msg/Type`), its serialization format (always
//! `cdr`) and QoS, and the messages: a log time (ns since the epoch, when the recorder received
//! it) and the message as serialized CDR *including* the 4-byte encapsulation header, exactly as
//! it travelled over DDS (so [`from_cdr_msg`] decodes it as is; a message an earlier version
//! of its type wrote, before fields were appended to it, too).
//!
//! - MCAP (`.mcap`, default since Iron), see [`mcap`]: the `ros2` profile; every
//!   type's complete `.msg` definition is stored in a schema record (see
//!   [`crate::interfaces::definition`]).
//! - sqlite3 (`.db3`, default up to Humble), see [`sqlite`]: tables `topics` and `messages`.
//!
//! [`Bag::open`] takes a bag directory, its `metadata.yaml`, or a bare `.mcap` / `.db3` file; a
//! directory without `metadata.yaml` is read if it holds `.mcap` or `.db3` files. Bags whose
//! files are compressed as a whole (`compression_mode: file` / `message`) are refused with a
//! clear error; compressed *chunks* inside an MCAP file (what rosbag2's MCAP presets do) are read.
//!
//! [`BagWriter`] writes an MCAP bag, as a directory (`NAME/NAME_0.mcap` and
//! `NAME/metadata.yaml`, rosbag2 version 9) or as a bare `.mcap` file, that `ros2 bag`, rosbags
//! and Foxglove read.
//!
//! ```no_run
//! use std::path::Path;
//! use tracer_calib::io::bag::{Bag, BagWriter};
//! use tracer_calib::interfaces::RawScan;
//!
//! let mut out = BagWriter::create(Path::new("scans"))?;
//! out.write("/raw_scan", 1_700_000_000_000_000_000, &RawScan::default())?;
//! out.finish()?;
//!
//! let bag = Bag::open(Path::new("scans"))?;
//! for (log_time_ns, scan) in bag.read::<RawScan>("/raw_scan")? {
//!     println!("{log_time_ns}: scan {} with {} samples", scan.scan_id, scan.step.len());
//! }
//! # Ok::<(), tracer_calib::io::bag::BagError>(())
//! ```

pub mod mcap;
pub mod metadata;
pub mod sqlite;
mod writer;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::interfaces::{CdrError, RosMsg, definition, from_cdr_msg};

pub use writer::BagWriter;

/// Why a bag could not be read or written. Every message is one line naming the file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BagError {
    /// The path does not exist.
    #[error("{}: no such file or directory", .path.display())]
    NotFound {
        /// The path given.
        path: PathBuf,
    },
    /// Reading or writing a file failed.
    #[error("{}: {source}", .path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The path is neither a bag directory nor a storage file.
    #[error("{} is not a rosbag2 bag: {reason}", .path.display())]
    NotABag {
        /// The path given.
        path: PathBuf,
        /// What was found instead.
        reason: String,
    },
    /// `metadata.yaml` is unreadable or incomplete.
    #[error("{}: bad rosbag2 metadata: {reason}", .path.display())]
    Metadata {
        /// The `metadata.yaml`.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A bag this reader does not handle (another storage plugin, file compression).
    #[error("{}: unsupported bag: {reason}", .path.display())]
    Unsupported {
        /// The file.
        path: PathBuf,
        /// What is unsupported.
        reason: String,
    },
    /// An MCAP file that does not parse: truncated, damaged, or not MCAP.
    #[error("{}: truncated or corrupt MCAP file: {source}", .path.display())]
    Mcap {
        /// The storage file.
        path: PathBuf,
        /// The parser's complaint.
        #[source]
        source: ::mcap::McapError,
    },
    /// An sqlite3 file that sqlite cannot read (e.g. "file is not a database").
    #[error("{}: unreadable sqlite3 bag: {source}", .path.display())]
    Sqlite {
        /// The storage file.
        path: PathBuf,
        /// sqlite's complaint.
        #[source]
        source: rusqlite::Error,
    },
    /// A storage file whose content makes no sense.
    #[error("{}: damaged bag: {reason}", .path.display())]
    Corrupt {
        /// The storage file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The topic is not in the bag.
    #[error("topic {topic} not in {}; topics: {available}", .path.display())]
    TopicNotFound {
        /// The bag.
        path: PathBuf,
        /// The topic asked for.
        topic: String,
        /// The topics there are: `/raw_scan (tracer_calib_msgs/msg/RawScan, 3 messages), ...`.
        available: String,
    },
    /// The topic has another type than the one asked for (or, writing, than the one it was
    /// added with).
    #[error("topic {topic} in {} has type {found}, expected {expected}", .path.display())]
    WrongType {
        /// The bag.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// Its type in the bag.
        found: String,
        /// The type asked for.
        expected: String,
    },
    /// The topic's messages are not CDR.
    #[error("topic {topic} in {} is serialized as {found:?}, expected cdr", .path.display())]
    NotCdr {
        /// The bag.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// Its serialization format.
        found: String,
    },
    /// A message does not decode as the topic's type.
    #[error(
        "{}: message {index} of topic {topic} (log time {log_time_ns} ns) does not decode as {type_name}: {source}",
        .path.display()
    )]
    Decode {
        /// The bag.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// Index of the message in the topic, 0-based, in log-time order.
        index: usize,
        /// Its log time, ns.
        log_time_ns: u64,
        /// The type it should have.
        type_name: String,
        /// The decoder's complaint.
        #[source]
        source: CdrError,
    },
    /// Writing: the path exists and is not an empty directory.
    #[error("{}: exists already and is not an empty directory; not overwriting", .path.display())]
    Exists {
        /// The path given.
        path: PathBuf,
    },
    /// Writing: an empty topic name, or a message for a topic never added.
    #[error("{}: bad topic name {topic:?}", .path.display())]
    BadTopicName {
        /// The bag.
        path: PathBuf,
        /// The topic name.
        topic: String,
    },
    /// Writing: no message definition for the type, or one it depends on, is known (see
    /// [`crate::interfaces::KNOWN`]).
    #[error("cannot write {type_name} to a bag: its message definition is unknown (known: {})", known_types())]
    NoDefinition {
        /// The type.
        type_name: String,
    },
    /// Writing: a message that does not serialize.
    #[error("{}: topic {topic}: cannot serialize the message: {source}", .path.display())]
    Encode {
        /// The bag.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// The serializer's complaint.
        #[source]
        source: CdrError,
    },
    /// Writing the MCAP file failed.
    #[error("{}: writing MCAP: {source}", .path.display())]
    McapWrite {
        /// The storage file.
        path: PathBuf,
        /// The writer's complaint.
        #[source]
        source: ::mcap::McapError,
    },
}

fn known_types() -> String {
    definition::known_types().collect::<Vec<_>>().join(", ")
}

/// The storage plugin of a bag.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StorageFormat {
    /// MCAP (`.mcap`).
    Mcap,
    /// sqlite3 (`.db3`).
    Sqlite3,
}

impl StorageFormat {
    /// The rosbag2 `storage_identifier`: `mcap` or `sqlite3`.
    pub fn storage_identifier(self) -> &'static str {
        match self {
            StorageFormat::Mcap => "mcap",
            StorageFormat::Sqlite3 => "sqlite3",
        }
    }

    fn scan(self, file: &Path, want: Option<&str>) -> Result<(Vec<TopicInfo>, Vec<BagMessage>), BagError> {
        match self {
            StorageFormat::Mcap => mcap::scan(file, want),
            StorageFormat::Sqlite3 => sqlite::scan(file, want),
        }
    }
}

/// One recorded message, still serialized.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BagMessage {
    /// The topic, e.g. `/raw_scan`.
    pub topic: String,
    /// The topic's type, `pkg/msg/Type`.
    pub type_name: String,
    /// When the recorder received it, ns since the epoch.
    pub log_time_ns: u64,
    /// The message as CDR, including the 4-byte encapsulation header.
    pub data: Vec<u8>,
}

/// A topic of a bag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicInfo {
    /// The topic name, e.g. `/raw_scan`.
    pub name: String,
    /// Its type, `pkg/msg/Type` (empty if an MCAP channel has no schema).
    pub type_name: String,
    /// How its messages are serialized: `cdr` in every rosbag2 bag.
    pub serialization_format: String,
    /// How many messages it has.
    pub count: u64,
}

/// An opened bag: its storage files and its topics. Messages are read on demand.
#[derive(Debug, Clone)]
pub struct Bag {
    path: PathBuf,
    format: StorageFormat,
    files: Vec<PathBuf>,
    topics: Vec<TopicInfo>,
}

const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";
const SQLITE_MAGIC: &[u8] = b"SQLite format 3\0";

impl Bag {
    /// Opens a bag: a bag directory (with `metadata.yaml`, or else with `.mcap` or `.db3`
    /// files), its `metadata.yaml`, or a bare `.mcap` or `.db3` file. Reads every storage file
    /// once to list the topics, so a damaged file fails here.
    pub fn open(path: &Path) -> Result<Bag, BagError> {
        let meta = std::fs::metadata(path).map_err(|source| match source.kind() {
            std::io::ErrorKind::NotFound => BagError::NotFound { path: path.to_path_buf() },
            _ => BagError::Io { path: path.to_path_buf(), source },
        })?;
        let (format, files) = if meta.is_dir() {
            locate_in_dir(path)?
        } else if path.file_name().is_some_and(|n| n == "metadata.yaml") {
            locate_in_dir(path.parent().unwrap_or(Path::new(".")))?
        } else {
            (format_of_file(path)?, vec![path.to_path_buf()])
        };
        let mut topics: Vec<TopicInfo> = Vec::new();
        for file in &files {
            for t in format.scan(file, None)?.0 {
                match topics.iter_mut().find(|have| have.name == t.name) {
                    Some(have) => have.count += t.count,
                    None => topics.push(t),
                }
            }
        }
        topics.sort_by(|a, b| a.name.cmp(&b.name));
        Ok(Bag { path: path.to_path_buf(), format, files, topics })
    }

    /// The path the bag was opened with.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The storage plugin.
    pub fn format(&self) -> StorageFormat {
        self.format
    }

    /// The storage files, in the order of `metadata.yaml`.
    pub fn storage_files(&self) -> &[PathBuf] {
        &self.files
    }

    /// The topics, sorted by name.
    pub fn topics(&self) -> &[TopicInfo] {
        &self.topics
    }

    /// The topic called `name`, if the bag has it.
    pub fn topic(&self, name: &str) -> Option<&TopicInfo> {
        self.topics.iter().find(|t| t.name == name)
    }

    /// The topics of type `type_name` (`pkg/msg/Type`), e.g. to find the raw scans whatever
    /// their topic was remapped to.
    pub fn topics_of_type<'a>(&'a self, type_name: &'a str) -> impl Iterator<Item = &'a TopicInfo> + 'a {
        self.topics.iter().filter(move |t| t.type_name == type_name)
    }

    /// The error for a topic the bag lacks, listing the topics it has.
    fn topic_not_found(&self, topic: &str) -> BagError {
        let mut available = String::new();
        for (i, t) in self.topics.iter().enumerate() {
            let sep = if i == 0 { "" } else { ", " };
            let plural = if t.count == 1 { "" } else { "s" };
            let _ = write!(available, "{sep}{} ({}, {} message{plural})", t.name, t.type_name, t.count);
        }
        if available.is_empty() {
            available.push_str("none");
        }
        BagError::TopicNotFound { path: self.path.clone(), topic: topic.to_string(), available }
    }

    /// Every message of `topic`, serialized, in log-time order (messages with equal log times
    /// keep their order in the file).
    pub fn messages(&self, topic: &str) -> Result<Vec<BagMessage>, BagError> {
        if self.topic(topic).is_none() {
            return Err(self.topic_not_found(topic));
        }
        let mut out = Vec::new();
        for file in &self.files {
            out.extend(self.format.scan(file, Some(topic))?.1);
        }
        out.sort_by_key(|m| m.log_time_ns);
        Ok(out)
    }

    /// Every message of `topic` decoded as `T`, with its log time (ns), in log-time order.
    ///
    /// Fails if the topic is missing, has another type than `T::NAME`, is not CDR, or one of
    /// its messages does not decode.
    pub fn read<T: RosMsg>(&self, topic: &str) -> Result<Vec<(u64, T)>, BagError> {
        let info = self.topic(topic).ok_or_else(|| self.topic_not_found(topic))?;
        let expected = T::NAME.ros_name();
        if info.type_name != expected {
            return Err(BagError::WrongType {
                path: self.path.clone(),
                topic: topic.to_string(),
                found: if info.type_name.is_empty() { "(none: no schema)".to_string() } else { info.type_name.clone() },
                expected,
            });
        }
        if info.serialization_format != "cdr" {
            return Err(BagError::NotCdr {
                path: self.path.clone(),
                topic: topic.to_string(),
                found: info.serialization_format.clone(),
            });
        }
        self.messages(topic)?
            .into_iter()
            .enumerate()
            .map(|(index, m)| {
                from_cdr_msg::<T>(&m.data).map(|msg| (m.log_time_ns, msg)).map_err(|source| BagError::Decode {
                    path: self.path.clone(),
                    topic: topic.to_string(),
                    index,
                    log_time_ns: m.log_time_ns,
                    type_name: expected.clone(),
                    source,
                })
            })
            .collect()
    }
}

/// The storage plugin and files of a bag directory.
fn locate_in_dir(dir: &Path) -> Result<(StorageFormat, Vec<PathBuf>), BagError> {
    if dir.join("metadata.yaml").exists() {
        let m = metadata::read(dir)?;
        return Ok((m.format, m.files));
    }
    let entries = std::fs::read_dir(dir).map_err(|source| BagError::Io { path: dir.to_path_buf(), source })?;
    let mut mcap = Vec::new();
    let mut db3 = Vec::new();
    for entry in entries {
        let path = entry.map_err(|source| BagError::Io { path: dir.to_path_buf(), source })?.path();
        if !path.is_file() {
            continue;
        }
        match path.extension().and_then(|e| e.to_str()) {
            Some("mcap") => mcap.push(path),
            Some("db3") => db3.push(path),
            _ => {}
        }
    }
    let not_a_bag = |reason: &str| BagError::NotABag { path: dir.to_path_buf(), reason: reason.to_string() };
    let (format, mut files) = match (mcap.is_empty(), db3.is_empty()) {
        (false, true) => (StorageFormat::Mcap, mcap),
        (true, false) => (StorageFormat::Sqlite3, db3),
        (true, true) => return Err(not_a_bag("a directory without metadata.yaml and without .mcap or .db3 files")),
        (false, false) => return Err(not_a_bag("a directory without metadata.yaml, with both .mcap and .db3 files")),
    };
    files.sort();
    log::info!("{}: no metadata.yaml; reading {} {} file(s)", dir.display(), files.len(), format.storage_identifier());
    Ok((format, files))
}

/// The storage plugin of a bare file, by extension, else by its first bytes.
fn format_of_file(path: &Path) -> Result<StorageFormat, BagError> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("mcap") => return Ok(StorageFormat::Mcap),
        Some("db3") => return Ok(StorageFormat::Sqlite3),
        Some("zstd" | "zst" | "lz4") => {
            return Err(BagError::Unsupported {
                path: path.to_path_buf(),
                reason: "a compressed storage file; decompress it first".to_string(),
            });
        }
        _ => {}
    }
    let mut head = [0u8; 16];
    let n = {
        use std::io::Read;
        let mut f = std::fs::File::open(path).map_err(|source| BagError::Io { path: path.to_path_buf(), source })?;
        f.read(&mut head).map_err(|source| BagError::Io { path: path.to_path_buf(), source })?
    };
    if head[..n].starts_with(MCAP_MAGIC) {
        Ok(StorageFormat::Mcap)
    } else if head[..n].starts_with(SQLITE_MAGIC) {
        Ok(StorageFormat::Sqlite3)
    } else {
        Err(BagError::NotABag {
            path: path.to_path_buf(),
            reason: "expected a bag directory, its metadata.yaml, an .mcap or a .db3 file".to_string(),
        })
    }
}
