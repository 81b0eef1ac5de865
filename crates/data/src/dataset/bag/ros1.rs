//! ROS 1 `.bag` files (format 2.0) read through the `rosbag` crate: the index section lists
//! the connections (topic, type) and where each chunk is; chunks (uncompressed, bz2 or
//! lz4) are decompressed one at a time, for the pass and again for each frame's message.
//!
//! The crate maps the file into memory (pages are read as they are touched, and the
//! kernel may drop them again) and trusts the bag header's index position: the header is
//! checked here first, so a bag cut short (a recording that was killed, whose index was
//! never written) is a clear error instead of a crash.

use std::collections::HashMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use rosbag::{ChunkRecord, IndexRecord, MessageRecord, RosBag};

use super::msg::Wire;
use super::{Channel, Recording};
use crate::io::input::{open_kind, InputKind};
use crate::{Error, Result};

const MAGIC: &[u8] = b"#ROSBAG V2.0\n";
/// Longest bag header record read, bytes (rosbag pads it to 4096).
const MAX_BAG_HEADER_BYTES: u32 = 64 << 10;

/// A `.bag` file; after [`Recording::scan`] it knows where each topic's messages are.
pub struct Ros1 {
    path: PathBuf,
    bag: RosBag,
    /// Chunk positions, in file order.
    chunks: Vec<u64>,
    connections: HashMap<u32, Channel>,
    /// Each topic's messages: (chunk position, record index in the chunk).
    places: Mutex<HashMap<String, Vec<(u64, usize)>>>,
}

impl std::fmt::Debug for Ros1 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Ros1({})", self.path.display())
    }
}

fn bad(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::format(
        path,
        format!("not a readable ROS 1 bag (truncated, corrupt or another format): {e}"),
    )
}

/// The bag header's `index_pos`, checked against the file's length.
fn index_pos(path: &Path) -> Result<u64> {
    let (mut file, len) = open_kind(path, InputKind::Recording)?;
    let mut magic = [0u8; 13];
    if file.read_exact(&mut magic).is_err() || magic != MAGIC {
        return Err(Error::format(
            path,
            "not a ROS 1 bag (it does not start with #ROSBAG V2.0)",
        ));
    }
    let mut n = [0u8; 4];
    file.read_exact(&mut n).map_err(|e| bad(path, e))?;
    let n = u32::from_le_bytes(n);
    if n > MAX_BAG_HEADER_BYTES {
        return Err(bad(path, format!("a {n}-byte bag header")));
    }
    let mut header = vec![0u8; n as usize];
    file.read_exact(&mut header).map_err(|e| bad(path, e))?;
    let mut rest = header.as_slice();
    while rest.len() >= 4 {
        let flen = u32::from_le_bytes(rest[..4].try_into().expect("4 bytes")) as usize;
        let field = rest
            .get(4..4 + flen)
            .ok_or_else(|| bad(path, "a cut bag header"))?;
        if let Some(v) = field.strip_prefix(b"index_pos=") {
            let v: [u8; 8] = v.try_into().map_err(|_| bad(path, "a bad index_pos"))?;
            let pos = u64::from_le_bytes(v);
            if pos == 0 || pos > len {
                return Err(Error::format(
                    path,
                    format!(
                        "the bag has no index (index at byte {pos} of {len}: a recording cut \
                         short); run `rosbag reindex` on it first"
                    ),
                ));
            }
            return Ok(pos);
        }
        rest = &rest[4 + flen..];
    }
    Err(bad(path, "the bag header has no index_pos"))
}

impl Ros1 {
    /// Opens `path`: checks its header, maps it, reads its index.
    pub fn open(path: &Path) -> Result<Ros1> {
        index_pos(path)?;
        let bag = RosBag::new(path).map_err(|e| bad(path, e))?;
        let mut chunks = Vec::new();
        let mut connections = HashMap::new();
        for record in bag.index_records() {
            match record.map_err(|e| bad(path, e))? {
                IndexRecord::ChunkInfo(c) => chunks.push(c.chunk_pos),
                IndexRecord::Connection(c) => {
                    connections.insert(c.id, channel_of(&c));
                }
                IndexRecord::IndexData(_) => {}
            }
        }
        chunks.sort_unstable();
        Ok(Ros1 {
            path: path.to_path_buf(),
            bag,
            chunks,
            connections,
            places: Mutex::new(HashMap::new()),
        })
    }

    /// The records of the chunk at `pos`, decompressed, passed to `each` with their index.
    fn chunk(
        &self,
        pos: u64,
        each: &mut dyn FnMut(usize, MessageRecord<'_>) -> Result<bool>,
    ) -> Result<()> {
        let mut it = self.bag.chunk_records();
        it.seek(pos).map_err(|e| bad(&self.path, e))?;
        let chunk = match it.next() {
            Some(Ok(ChunkRecord::Chunk(c))) => c,
            Some(Err(e)) => return Err(bad(&self.path, e)),
            _ => return Err(bad(&self.path, format!("no chunk at byte {pos}"))),
        };
        for (i, record) in chunk.messages().enumerate() {
            if !each(i, record.map_err(|e| bad(&self.path, e))?)? {
                break;
            }
        }
        Ok(())
    }
}

fn channel_of(c: &rosbag::record_types::Connection<'_>) -> Channel {
    Channel {
        topic: c.topic.to_string(),
        msg_type: c.tp.to_string(),
        wire: Some(Wire::Ros1),
    }
}

impl Recording for Ros1 {
    fn scan(&self, visit: &mut dyn FnMut(&Channel, &[u8]) -> Result<()>) -> Result<()> {
        let mut connections = self.connections.clone();
        let mut places: HashMap<String, Vec<(u64, usize)>> = HashMap::new();
        for &pos in &self.chunks {
            self.chunk(pos, &mut |i, record| {
                match record {
                    MessageRecord::Connection(c) => {
                        connections.insert(c.id, channel_of(&c));
                    }
                    MessageRecord::MessageData(m) => {
                        let channel = connections.get(&m.conn_id).ok_or_else(|| {
                            bad(
                                &self.path,
                                format!("a message of undeclared connection {}", m.conn_id),
                            )
                        })?;
                        places
                            .entry(channel.topic.clone())
                            .or_default()
                            .push((pos, i));
                        visit(channel, m.data)?;
                    }
                }
                Ok(true)
            })?;
        }
        *self.places.lock().unwrap_or_else(|e| e.into_inner()) = places;
        Ok(())
    }

    fn message(&self, topic: &str, ordinal: usize) -> Result<Vec<u8>> {
        let (pos, index) = super::nth_message(&self.places, topic, ordinal, &self.path)?;
        let mut out = None;
        self.chunk(pos, &mut |i, record| {
            if i == index {
                if let MessageRecord::MessageData(m) = record {
                    out = Some(m.data.to_vec());
                }
                return Ok(false);
            }
            Ok(true)
        })?;
        out.ok_or_else(|| {
            Error::format(&self.path, format!("message {ordinal} of {topic} is gone"))
        })
    }
}
