//! ROS 2 bags in SQLite (`.db3`, rosbag2's first storage) read through `rusqlite`: the
//! `topics` table names each topic's type and serialisation, the `messages` table holds
//! each message (CDR) by topic and receive time. Rows are stepped one at a time, and a
//! message longer than the cap is refused by its length before its bytes are read.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use rusqlite::{Connection, OpenFlags};

use super::msg::Wire;
use super::{Channel, Recording};
use crate::io::input::{open_kind, InputKind};
use crate::{Error, Result};

/// A `.db3` file; after [`Recording::scan`] it knows each topic's message row ids.
#[derive(Debug)]
pub struct Db3 {
    path: PathBuf,
    conn: Mutex<Connection>,
    channels: HashMap<i64, Channel>,
    /// Row ids of each topic's messages, in the scan's order.
    rows: Mutex<HashMap<String, Vec<i64>>>,
}

impl Db3 {
    fn bad(path: &Path, e: impl std::fmt::Display) -> Error {
        Error::format(
            path,
            format!("not a readable ROS 2 SQLite bag (truncated, corrupt or another format): {e}"),
        )
    }

    /// Opens `path` read-only and reads its topics.
    pub fn open(path: &Path) -> Result<Db3> {
        // A regular file, not a FIFO or a folder, before SQLite opens it.
        open_kind(path, InputKind::Recording)?;
        let flags = OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX;
        let conn = Connection::open_with_flags(path, flags).map_err(|e| Self::bad(path, e))?;
        let mut channels = HashMap::new();
        {
            let mut stmt = conn
                .prepare("SELECT id, name, type, serialization_format FROM topics")
                .map_err(|e| Self::bad(path, e))?;
            let mut rows = stmt.query([]).map_err(|e| Self::bad(path, e))?;
            while let Some(row) = rows.next().map_err(|e| Self::bad(path, e))? {
                let get = |i| row.get::<_, String>(i).map_err(|e| Self::bad(path, e));
                let id: i64 = row.get(0).map_err(|e| Self::bad(path, e))?;
                let wire = match get(3)?.as_str() {
                    "cdr" => Some(Wire::Cdr),
                    _ => None,
                };
                channels.insert(
                    id,
                    Channel {
                        topic: get(1)?,
                        msg_type: get(2)?,
                        wire,
                    },
                );
            }
        }
        Ok(Db3 {
            path: path.to_path_buf(),
            conn: Mutex::new(conn),
            channels,
            rows: Mutex::new(HashMap::new()),
        })
    }

    fn too_long(&self, len: i64, cap: u64) -> Error {
        Error::format(
            &self.path,
            format!("a message of {len} bytes, more than the {cap}-byte cap"),
        )
    }
}

impl Recording for Db3 {
    fn scan(&self, visit: &mut dyn FnMut(&Channel, &[u8]) -> Result<()>) -> Result<()> {
        let cap = super::max_message_bytes()?;
        let conn = self.conn.lock().unwrap_or_else(|e| e.into_inner());
        let bad = |e| Self::bad(&self.path, e);
        let mut stmt = conn
            .prepare(
                "SELECT id, topic_id, length(data), \
                 CASE WHEN length(data) <= ?1 THEN data END \
                 FROM messages ORDER BY timestamp, id",
            )
            .map_err(bad)?;
        let mut rows = stmt.query([cap as i64]).map_err(bad)?;
        let mut ids: HashMap<String, Vec<i64>> = HashMap::new();
        while let Some(row) = rows.next().map_err(bad)? {
            let (id, topic, len): (i64, i64, i64) = (
                row.get(0).map_err(bad)?,
                row.get(1).map_err(bad)?,
                row.get(2).map_err(bad)?,
            );
            let channel = self.channels.get(&topic).ok_or_else(|| {
                Self::bad(
                    &self.path,
                    format!("a message of undeclared topic id {topic}"),
                )
            })?;
            let data: Option<Vec<u8>> = row.get(3).map_err(bad)?;
            let data = data.ok_or_else(|| self.too_long(len, cap))?;
            ids.entry(channel.topic.clone()).or_default().push(id);
            visit(channel, &data)?;
        }
        *self.rows.lock().unwrap_or_else(|e| e.into_inner()) = ids;
        Ok(())
    }

    fn message(&self, topic: &str, ordinal: usize) -> Result<Vec<u8>> {
        let id = super::nth_message(&self.rows, topic, ordinal, &self.path)?;
        let conn = self.conn.lock().unwrap_or_else(|e| e.into_inner());
        conn.query_row("SELECT data FROM messages WHERE id = ?1", [id], |r| {
            r.get(0)
        })
        .map_err(|e| Self::bad(&self.path, e))
    }
}
