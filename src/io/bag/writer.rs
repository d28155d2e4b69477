//! [`BagWriter`]: MCAP bags of the rosbag2 `ros2` profile.

use std::path::{Path, PathBuf};

use super::mcap::McapFile;
use super::{BagError, metadata};
use crate::interfaces::{RosMsg, definition, to_cdr};

/// Writes an MCAP rosbag2 bag.
///
/// A path ending in `.mcap` gives a bare MCAP file (overwritten if it exists); any other path a
/// bag directory `NAME/` holding `NAME_0.mcap` and `metadata.yaml`, like `ros2 bag record -s mcap`
/// (the directory must not exist, or be empty). Topics carry the complete message definition
/// of their type, so any rosbag2 tool can decode them; the types with known definitions are
/// listed in [`KNOWN`](crate::interfaces::KNOWN).
///
/// Call [`BagWriter::finish`]: it completes the MCAP file and writes `metadata.yaml`, and
/// reports errors. Dropping an unfinished writer finishes it too, logging any error.
pub struct BagWriter {
    path: PathBuf,
    /// `Some` for a bag directory.
    dir: Option<PathBuf>,
    file_name: String,
    file: Option<McapFile>,
}

impl BagWriter {
    /// Creates the bag at `path`: a bare MCAP file if `path` ends in `.mcap`, else a bag directory.
    pub fn create(path: &Path) -> Result<BagWriter, BagError> {
        let bare = path.extension().is_some_and(|e| e == "mcap");
        let (dir, mcap_path) = if bare {
            (None, path.to_path_buf())
        } else {
            match std::fs::read_dir(path) {
                Ok(mut entries) => {
                    if entries.next().is_some() {
                        return Err(BagError::Exists { path: path.to_path_buf() });
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                    std::fs::create_dir_all(path)
                        .map_err(|source| BagError::Io { path: path.to_path_buf(), source })?;
                }
                Err(e) if e.kind() == std::io::ErrorKind::NotADirectory || path.is_file() => {
                    return Err(BagError::Exists { path: path.to_path_buf() });
                }
                Err(source) => return Err(BagError::Io { path: path.to_path_buf(), source }),
            }
            let name = path
                .canonicalize()
                .ok()
                .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
                .unwrap_or_else(|| "bag".to_string());
            (Some(path.to_path_buf()), path.join(format!("{name}_0.mcap")))
        };
        let file_name = mcap_path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let file = McapFile::create(&mcap_path)?;
        Ok(BagWriter { path: path.to_path_buf(), dir, file_name, file: Some(file) })
    }

    /// The path the bag is written to.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn file(&mut self) -> &mut McapFile {
        self.file.as_mut().expect("BagWriter used after finish")
    }

    /// Adds topic `name` of type `T`, so that it is listed even without messages. [`write`]
    /// adds topics by itself; adding a topic again with the same type does nothing, with
    /// another type is an error.
    ///
    /// [`write`]: BagWriter::write
    pub fn add_topic<T: RosMsg>(&mut self, name: &str) -> Result<(), BagError> {
        self.file().add_channel(name, &T::NAME.ros_name(), definition::full_definition_of::<T>)
    }

    /// Writes `msg` to `topic` with log time `log_time_ns` (ns since the epoch; also used as
    /// the publish time). Messages need not come in time order.
    pub fn write<T: RosMsg>(&mut self, topic: &str, log_time_ns: u64, msg: &T) -> Result<(), BagError> {
        self.add_topic::<T>(topic)?;
        let data = to_cdr(msg).map_err(|source| BagError::Encode {
            path: self.path.clone(),
            topic: topic.to_string(),
            source,
        })?;
        self.file().write(topic, log_time_ns, &data)
    }

    /// Completes the MCAP file, writes `metadata.yaml` for a bag directory, and returns the
    /// bag's path.
    pub fn finish(mut self) -> Result<PathBuf, BagError> {
        self.finish_inner()?;
        Ok(std::mem::take(&mut self.path))
    }

    fn finish_inner(&mut self) -> Result<(), BagError> {
        let Some(file) = self.file.take() else { return Ok(()) };
        let yaml = metadata::metadata_yaml(&file.summary(&self.file_name));
        file.finish()?;
        if let Some(dir) = &self.dir {
            let path = dir.join("metadata.yaml");
            std::fs::write(&path, yaml).map_err(|source| BagError::Io { path, source })?;
        }
        Ok(())
    }
}

impl Drop for BagWriter {
    fn drop(&mut self) {
        if self.file.is_some()
            && let Err(e) = self.finish_inner()
        {
            log::error!("{e}");
        }
    }
}
