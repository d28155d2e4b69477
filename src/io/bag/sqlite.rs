//! sqlite3 storage files (`.db3`), the rosbag2 default up to Humble.
//!
//! Schema version 4 (Iron and later) has the tables
//!
//! ```text
//! schema(schema_version, ros_distro)
//! metadata(id, metadata_version, metadata)
//! topics(id, name, type, serialization_format, offered_qos_profiles, type_description_hash)
//! message_definitions(id, topic_type, encoding, encoded_message_definition, type_description_hash)
//! messages(id, topic_id, timestamp, data)      -- timestamp: log time, ns; data: CDR bytes
//! ```
//!
//! Older versions lack `schema`, `metadata`, `message_definitions` and some `topics` columns; the
//! reader uses only `topics(id, name, type, serialization_format)` and `messages`, which every
//! version has.

use std::collections::HashMap;
use std::path::Path;

use rusqlite::{Connection, OpenFlags};

use super::{BagError, BagMessage, TopicInfo};

fn open(path: &Path) -> Result<Connection, BagError> {
    let err = |source| BagError::Sqlite { path: path.to_path_buf(), source };
    let conn = Connection::open_with_flags(path, OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX)
        .map_err(err)?;
    // The first read of the file: "file is not a database" shows here.
    let mut stmt = conn.prepare("SELECT name FROM sqlite_master WHERE type = 'table'").map_err(err)?;
    let tables: Vec<String> =
        stmt.query_map([], |row| row.get(0)).map_err(err)?.collect::<Result<_, _>>().map_err(err)?;
    drop(stmt);
    let missing: Vec<&str> = ["topics", "messages"].into_iter().filter(|t| !tables.iter().any(|n| n == t)).collect();
    if !missing.is_empty() {
        return Err(BagError::NotABag {
            path: path.to_path_buf(),
            reason: format!("an sqlite3 database without the rosbag2 table(s) {}", missing.join(", ")),
        });
    }
    Ok(conn)
}

struct Topic {
    id: i64,
    name: String,
    type_name: String,
    serialization_format: String,
}

fn topic_rows(conn: &Connection, path: &Path) -> Result<Vec<Topic>, BagError> {
    let err = |source| BagError::Sqlite { path: path.to_path_buf(), source };
    let mut stmt = conn.prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id").map_err(err)?;
    let rows = stmt
        .query_map([], |row| {
            Ok(Topic { id: row.get(0)?, name: row.get(1)?, type_name: row.get(2)?, serialization_format: row.get(3)? })
        })
        .map_err(err)?;
    rows.collect::<Result<_, _>>().map_err(err)
}

/// Reads an sqlite3 storage file: its topics with message counts and, for `want = Some(topic)`,
/// the messages of that topic.
pub(crate) fn scan(path: &Path, want: Option<&str>) -> Result<(Vec<TopicInfo>, Vec<BagMessage>), BagError> {
    let err = |source| BagError::Sqlite { path: path.to_path_buf(), source };
    let conn = open(path)?;
    let rows = topic_rows(&conn, path)?;
    let mut counts: HashMap<i64, u64> = HashMap::new();
    {
        let mut stmt = conn.prepare("SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id").map_err(err)?;
        let mut q = stmt.query([]).map_err(err)?;
        while let Some(row) = q.next().map_err(err)? {
            let n: i64 = row.get(1).map_err(err)?;
            counts.insert(row.get(0).map_err(err)?, u64::try_from(n).unwrap_or(0));
        }
    }
    let mut topics: Vec<TopicInfo> = Vec::new();
    for r in &rows {
        let count = counts.get(&r.id).copied().unwrap_or(0);
        match topics.iter_mut().find(|t| t.name == r.name) {
            Some(t) => t.count += count,
            None => topics.push(TopicInfo {
                name: r.name.clone(),
                type_name: r.type_name.clone(),
                serialization_format: r.serialization_format.clone(),
                count,
            }),
        }
    }
    let mut messages = Vec::new();
    if let Some(want) = want {
        let mut stmt = conn
            .prepare("SELECT timestamp, data FROM messages WHERE topic_id = ?1 ORDER BY timestamp, id")
            .map_err(err)?;
        for r in rows.iter().filter(|r| r.name == want) {
            let mut q = stmt.query([r.id]).map_err(err)?;
            while let Some(row) = q.next().map_err(err)? {
                let timestamp: i64 = row.get(0).map_err(err)?;
                let log_time_ns = u64::try_from(timestamp).map_err(|_| BagError::Corrupt {
                    path: path.to_path_buf(),
                    reason: format!("a message of topic {want} has the negative timestamp {timestamp}"),
                })?;
                messages.push(BagMessage {
                    topic: r.name.clone(),
                    type_name: r.type_name.clone(),
                    log_time_ns,
                    data: row.get(1).map_err(err)?,
                });
            }
        }
    }
    Ok((topics, messages))
}
