//! MCAP storage files (`.mcap`), the rosbag2 default since Iron.
//!
//! An MCAP file is a sequence of records between two magic strings: a header (profile `ros2`
//! for rosbag2), schema records (one per message type: encoding `ros2msg`, name `pkg/msg/Type`,
//! data the complete `.msg` definition), channel records (one per topic: message encoding `cdr`,
//! metadata `offered_qos_profiles`), and message records (channel, log time, publish time, CDR
//! bytes with the encapsulation header), usually grouped in zstd- or lz4-compressed chunks; then
//! a summary section that repeats schemas and channels and indexes the chunks.
//!
//! The reader scans the file from start to end (chunks unpacked, chunk CRCs checked), so a
//! truncated or damaged file is an error rather than a silently shorter bag.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use mcap::read::{ChunkFlattener, Options};
use mcap::records::{MessageHeader, Metadata, Record};
use mcap::{Compression, McapError, WriteOptions, Writer};

use super::{BagError, BagMessage, TopicInfo, metadata};

struct ChannelInfo {
    topic: String,
    schema_id: u16,
    encoding: String,
}

/// Scans an MCAP file: its topics with message counts and, for `want = Some(topic)`, the messages
/// of that topic in file order.
pub(crate) fn scan(path: &Path, want: Option<&str>) -> Result<(Vec<TopicInfo>, Vec<BagMessage>), BagError> {
    let bytes = std::fs::read(path).map_err(|source| BagError::Io { path: path.to_path_buf(), source })?;
    let corrupt = |source: McapError| BagError::Mcap { path: path.to_path_buf(), source };
    let mut schemas: HashMap<u16, String> = HashMap::new();
    let mut channels: BTreeMap<u16, ChannelInfo> = BTreeMap::new();
    let mut counts: HashMap<u16, u64> = HashMap::new();
    let mut messages = Vec::new();
    for record in ChunkFlattener::new_with_options(&bytes, Options::ValidateChunkCrcs.into()).map_err(corrupt)? {
        match record.map_err(corrupt)? {
            Record::Schema { header, .. } => {
                schemas.insert(header.id, header.name);
            }
            Record::Channel(c) => {
                channels
                    .insert(c.id, ChannelInfo { topic: c.topic, schema_id: c.schema_id, encoding: c.message_encoding });
            }
            Record::Message { header, data } => {
                let channel = channels
                    .get(&header.channel_id)
                    .ok_or_else(|| corrupt(McapError::UnknownChannel(header.sequence, header.channel_id)))?;
                *counts.entry(header.channel_id).or_default() += 1;
                if want == Some(channel.topic.as_str()) {
                    messages.push(BagMessage {
                        topic: channel.topic.clone(),
                        type_name: schemas.get(&channel.schema_id).cloned().unwrap_or_default(),
                        log_time_ns: header.log_time,
                        data: data.into_owned(),
                    });
                }
            }
            _ => {}
        }
    }
    let mut topics: Vec<TopicInfo> = Vec::new();
    for (id, c) in &channels {
        let count = counts.get(id).copied().unwrap_or(0);
        let type_name = schemas.get(&c.schema_id).cloned().unwrap_or_default();
        match topics.iter_mut().find(|t| t.name == c.topic) {
            Some(t) => {
                if t.type_name != type_name {
                    log::warn!(
                        "{}: topic {} has channels of types {} and {}; reporting {}",
                        path.display(),
                        c.topic,
                        t.type_name,
                        type_name,
                        t.type_name
                    );
                }
                t.count += count;
            }
            None => topics.push(TopicInfo {
                name: c.topic.clone(),
                type_name,
                serialization_format: c.encoding.clone(),
                count,
            }),
        }
    }
    Ok((topics, messages))
}

struct Channel {
    id: u16,
    name: String,
    type_name: String,
    count: u64,
    next_sequence: u32,
}

/// Writes one MCAP storage file of the rosbag2 `ros2` profile.
pub(crate) struct McapFile {
    path: PathBuf,
    writer: Writer<BufWriter<File>>,
    schemas: HashMap<String, u16>,
    channels: Vec<Channel>,
    time_range: Option<(u64, u64)>,
}

impl McapFile {
    pub fn create(path: &Path) -> Result<McapFile, BagError> {
        let file = File::create(path).map_err(|source| BagError::Io { path: path.to_path_buf(), source })?;
        let writer = WriteOptions::new()
            .profile("ros2")
            .library(concat!("tracer_calib ", env!("CARGO_PKG_VERSION")))
            .compression(Some(Compression::Zstd))
            .compression_threads(0)
            .create(BufWriter::new(file))
            .map_err(|source| BagError::McapWrite { path: path.to_path_buf(), source })?;
        Ok(McapFile {
            path: path.to_path_buf(),
            writer,
            schemas: HashMap::new(),
            channels: Vec::new(),
            time_range: None,
        })
    }

    fn write_error(&self, source: McapError) -> BagError {
        BagError::McapWrite { path: self.path.clone(), source }
    }

    /// Adds channel `topic` of type `type_name` (`pkg/msg/Type`), and the type's schema record the
    /// first time it is seen, with the complete definition `definition` gives (`None`: the
    /// type or one of its dependencies is unknown, an error). Adding the same topic with the
    /// same type again does nothing.
    pub fn add_channel(
        &mut self,
        topic: &str,
        type_name: &str,
        definition: impl FnOnce() -> Option<String>,
    ) -> Result<(), BagError> {
        if let Some(c) = self.channels.iter().find(|c| c.name == topic) {
            if c.type_name == type_name {
                return Ok(());
            }
            return Err(BagError::WrongType {
                path: self.path.clone(),
                topic: topic.to_string(),
                found: c.type_name.clone(),
                expected: type_name.to_string(),
            });
        }
        if topic.is_empty() {
            return Err(BagError::BadTopicName { path: self.path.clone(), topic: topic.to_string() });
        }
        let schema_id = match self.schemas.get(type_name) {
            Some(&id) => id,
            None => {
                let definition =
                    definition().ok_or_else(|| BagError::NoDefinition { type_name: type_name.to_string() })?;
                let id = self
                    .writer
                    .add_schema(type_name, "ros2msg", definition.as_bytes())
                    .map_err(|e| self.write_error(e))?;
                self.schemas.insert(type_name.to_string(), id);
                id
            }
        };
        let meta = BTreeMap::from([("offered_qos_profiles".to_string(), metadata::OFFERED_QOS_PROFILES.to_string())]);
        let id = self.writer.add_channel(schema_id, topic, "cdr", &meta).map_err(|e| self.write_error(e))?;
        self.channels.push(Channel {
            id,
            name: topic.to_string(),
            type_name: type_name.to_string(),
            count: 0,
            next_sequence: 0,
        });
        Ok(())
    }

    /// Writes one message (CDR with its encapsulation header) to an added channel.
    pub fn write(&mut self, topic: &str, log_time_ns: u64, data: &[u8]) -> Result<(), BagError> {
        let Some(c) = self.channels.iter_mut().find(|c| c.name == topic) else {
            return Err(BagError::BadTopicName { path: self.path.clone(), topic: topic.to_string() });
        };
        let header = MessageHeader {
            channel_id: c.id,
            sequence: c.next_sequence,
            log_time: log_time_ns,
            publish_time: log_time_ns,
        };
        c.next_sequence = c.next_sequence.wrapping_add(1);
        c.count += 1;
        self.time_range = Some(match self.time_range {
            None => (log_time_ns, log_time_ns),
            Some((a, b)) => (a.min(log_time_ns), b.max(log_time_ns)),
        });
        let result = self.writer.write_to_known_channel(&header, data);
        result.map_err(|e| self.write_error(e))
    }

    /// The summary `metadata.yaml` and the `rosbag2` metadata record describe.
    pub fn summary<'a>(&'a self, file_name: &'a str) -> metadata::Summary<'a> {
        metadata::Summary {
            file_name,
            time_range: self.time_range,
            topics: self
                .channels
                .iter()
                .map(|c| metadata::TopicEntry { name: &c.name, type_name: &c.type_name, count: c.count })
                .collect(),
        }
    }

    /// Writes the `rosbag2` metadata record (as rosbag2 does: the bag information as YAML), the
    /// summary section and the footer, and flushes the file.
    pub fn finish(mut self) -> Result<(), BagError> {
        let file_name = self.path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let info = metadata::to_text(&metadata::bagfile_information(&self.summary(&file_name)));
        let record = Metadata {
            name: "rosbag2".to_string(),
            metadata: BTreeMap::from([
                ("serialized_metadata".to_string(), info),
                ("ROS_DISTRO".to_string(), String::new()),
            ]),
        };
        self.writer.write_metadata(&record).map_err(|e| self.write_error(e))?;
        self.writer.finish().map_err(|e| self.write_error(e))?;
        let path = self.path;
        let mut inner = self.writer.into_inner();
        inner.flush().map_err(|source| BagError::Io { path: path.clone(), source })?;
        inner.get_ref().sync_all().map_err(|source| BagError::Io { path, source })
    }
}
