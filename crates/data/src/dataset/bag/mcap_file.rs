//! MCAP recordings (a ROS 2 bag's `.mcap`, or a single `.mcap` file) read through the
//! `mcap` crate's streaming reader: the file is fed to it in pieces and its chunks are
//! decompressed one at a time (zstd, lz4), so memory stays at about one chunk.
//!
//! Messages of channels encoded `cdr` (ROS 2) or `ros1` are decoded; other encodings
//! (JSON, protobuf) are listed as topics but never read.

use std::collections::HashMap;
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};

use super::msg::Wire;
use super::{Channel, Recording};
use crate::io::input::{open_kind, InputKind};
use crate::{Error, Result};

/// An MCAP file; messages are found again by streaming from the start (or from where the
/// last request for the same topic stopped).
#[derive(Debug)]
pub struct McapFile {
    path: PathBuf,
    /// Per topic, a stream left after the last message handed out, and that message's
    /// ordinal + 1: frames are asked for in order, so each is a short step forward.
    cursors: Mutex<HashMap<String, (Stream, usize)>>,
}

/// A pass over the file's records.
struct Stream {
    path: PathBuf,
    file: std::io::Take<File>,
    reader: LinearReader,
    schemas: HashMap<u16, String>,
    channels: HashMap<u16, Channel>,
}

impl std::fmt::Debug for Stream {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Stream({})", self.path.display())
    }
}

impl Stream {
    fn open(path: &Path) -> Result<Stream> {
        let (file, _) = open_kind(path, InputKind::Recording)?;
        let limit = usize::try_from(super::max_message_bytes()?).unwrap_or(usize::MAX);
        let options = LinearReaderOptions::default()
            .with_record_length_limit(limit)
            .with_validate_chunk_crcs(true);
        Ok(Stream {
            path: path.to_path_buf(),
            file,
            reader: LinearReader::new_with_options(options),
            schemas: HashMap::new(),
            channels: HashMap::new(),
        })
    }

    fn bad(&self, what: impl std::fmt::Display) -> Error {
        Error::format(
            &self.path,
            format!("not a readable MCAP file (truncated, corrupt or another format): {what}"),
        )
    }

    /// The next message: its channel and bytes; `None` at the end of the file.
    fn next(&mut self) -> Result<Option<(Channel, Vec<u8>)>> {
        loop {
            let event = match self.reader.next_event() {
                None => return Ok(None),
                Some(Err(e)) => return Err(self.bad(e)),
                Some(Ok(event)) => event,
            };
            let (opcode, data) = match event {
                LinearReadEvent::ReadRequest(n) => {
                    let buf = self.reader.insert(n);
                    let got = self.file.read(buf).map_err(|e| Error::io(&self.path, e))?;
                    self.reader.notify_read(got);
                    continue;
                }
                LinearReadEvent::Record { data, opcode } => (opcode, data.to_vec()),
            };
            match mcap::parse_record(opcode, &data).map_err(|e| self.bad(e))? {
                mcap::records::Record::Schema { header, .. } => {
                    self.schemas.insert(header.id, header.name);
                }
                mcap::records::Record::Channel(c) => {
                    let wire = match c.message_encoding.as_str() {
                        "cdr" => Some(Wire::Cdr),
                        "ros1" => Some(Wire::Ros1),
                        _ => None,
                    };
                    let msg_type = self.schemas.get(&c.schema_id).cloned().unwrap_or_default();
                    let channel = Channel {
                        topic: c.topic,
                        msg_type,
                        wire,
                    };
                    self.channels.insert(c.id, channel);
                }
                mcap::records::Record::Message { header, data } => {
                    let channel = self.channels.get(&header.channel_id).ok_or_else(|| {
                        self.bad(format!(
                            "a message on undeclared channel {}",
                            header.channel_id
                        ))
                    })?;
                    return Ok(Some((channel.clone(), data.into_owned())));
                }
                _ => {}
            }
        }
    }
}

impl McapFile {
    /// Opens `path`, checking its magic bytes: a file of another format is an error here.
    pub fn new(path: &Path) -> Result<McapFile> {
        let mut magic = [0u8; 8];
        let (mut file, _) = open_kind(path, InputKind::Recording)?;
        if file.read_exact(&mut magic).is_err() || magic != *mcap::MAGIC {
            return Err(Error::format(
                path,
                "not an MCAP file (it does not start with MCAP's magic bytes)",
            ));
        }
        Ok(McapFile {
            path: path.to_path_buf(),
            cursors: Mutex::new(HashMap::new()),
        })
    }
}

impl Recording for McapFile {
    fn scan(&self, visit: &mut dyn FnMut(&Channel, &[u8]) -> Result<()>) -> Result<()> {
        let mut stream = Stream::open(&self.path)?;
        while let Some((channel, bytes)) = stream.next()? {
            visit(&channel, &bytes)?;
        }
        Ok(())
    }

    fn message(&self, topic: &str, ordinal: usize) -> Result<Vec<u8>> {
        let mut cursors = self.cursors.lock().unwrap_or_else(|e| e.into_inner());
        let (mut stream, mut next) = match cursors.remove(topic) {
            Some((s, n)) if n <= ordinal => (s, n),
            _ => (Stream::open(&self.path)?, 0),
        };
        while let Some((channel, bytes)) = stream.next()? {
            if channel.topic != topic {
                continue;
            }
            next += 1;
            if next == ordinal + 1 {
                cursors.insert(topic.to_string(), (stream, next));
                return Ok(bytes);
            }
        }
        Err(Error::format(
            &self.path,
            format!("message {ordinal} of {topic} is gone (the file changed since it was opened)"),
        ))
    }
}
