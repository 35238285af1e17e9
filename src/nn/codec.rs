//! A minimal little-endian binary codec for parameter files and checkpoints.
//!
//! Binary rather than JSON because checkpoints must restore `f32` parameters bit for bit and
//! hold replay buffers of up to millions of transitions.

use std::path::Path;

/// A binary file (parameters, checkpoint, policy) that cannot be read, written or decoded,
/// naming the file: the part every such file's error type shares.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {source}")]
    Codec {
        path: String,
        #[source]
        source: CodecError,
    },
}

impl FileError {
    /// Names `path` in the codec errors of a reader of that file (for `map_err`).
    pub fn codec_at(path: &str) -> impl Fn(CodecError) -> FileError + Copy + '_ {
        move |source| FileError::Codec {
            path: path.to_string(),
            source,
        }
    }
}

/// Largest file of this codec read: 4 GiB, the size of a SAC snapshot with a replay buffer of
/// 4 million transitions of ~250 floats (the buffer's limit is 4 million,
/// `rl::sac::config::MAX_REPLAY_CAPACITY`; the project's observations have under 40).
pub const MAX_CODEC_FILE_BYTES: u64 = 4 << 30;

/// Reads the whole file at `path`, at most [`MAX_CODEC_FILE_BYTES`] (the counts inside are
/// checked against the bytes present when it is decoded).
pub fn read_file(path: &Path) -> Result<Vec<u8>, FileError> {
    crate::input_file::read_bytes(path, MAX_CODEC_FILE_BYTES).map_err(|source| FileError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// Writes `bytes` to `path` atomically (see [`crate::atomic_file::write_atomic`]).
pub fn save_file(path: &Path, bytes: &[u8]) -> Result<(), FileError> {
    crate::atomic_file::write_atomic(path, bytes).map_err(|source| FileError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// A malformed or truncated binary file.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CodecError {
    #[error("file ends early while reading {what} (needs {needed} more bytes, {left} left)")]
    UnexpectedEnd {
        what: &'static str,
        needed: usize,
        left: usize,
    },
    #[error("not a {expected} file (magic bytes differ)")]
    BadMagic { expected: &'static str },
    #[error(
        "{what} format version {found} is not supported (this build reads version {supported})"
    )]
    Version {
        what: &'static str,
        found: u32,
        supported: u32,
    },
    #[error("{what}: {problem}")]
    Invalid { what: &'static str, problem: String },
    #[error("{0} trailing bytes after the end of the data")]
    Trailing(usize),
}

/// Appends values to a byte buffer.
#[derive(Default)]
pub struct ByteWriter {
    pub bytes: Vec<u8>,
}

impl ByteWriter {
    pub fn new() -> Self {
        Self::default()
    }
    pub fn u8(&mut self, v: u8) {
        self.bytes.push(v);
    }
    pub fn u32(&mut self, v: u32) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }
    pub fn u64(&mut self, v: u64) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }
    pub fn u128(&mut self, v: u128) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }
    pub fn f32(&mut self, v: f32) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }
    pub fn usize(&mut self, v: usize) {
        self.u64(v as u64);
    }
    pub fn raw(&mut self, v: &[u8]) {
        self.bytes.extend_from_slice(v);
    }
    /// Length-prefixed bytes.
    pub fn blob(&mut self, v: &[u8]) {
        self.usize(v.len());
        self.raw(v);
    }
    pub fn str(&mut self, v: &str) {
        self.blob(v.as_bytes());
    }
    /// Length-prefixed `f32` slice.
    pub fn f32s(&mut self, v: &[f32]) {
        self.usize(v.len());
        self.bytes.reserve(v.len() * 4);
        for x in v {
            self.bytes.extend_from_slice(&x.to_le_bytes());
        }
    }
    pub fn u32s(&mut self, v: &[u32]) {
        self.usize(v.len());
        for x in v {
            self.bytes.extend_from_slice(&x.to_le_bytes());
        }
    }
}

/// Reads values back in the order a [`ByteWriter`] wrote them.
pub struct ByteReader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> ByteReader<'a> {
    pub fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, pos: 0 }
    }
    fn take(&mut self, n: usize, what: &'static str) -> Result<&'a [u8], CodecError> {
        let left = self.bytes.len() - self.pos;
        if n > left {
            return Err(CodecError::UnexpectedEnd {
                what,
                needed: n,
                left,
            });
        }
        let s = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    /// Checks the magic bytes at the current position.
    pub fn magic(&mut self, magic: &[u8], expected: &'static str) -> Result<(), CodecError> {
        let left = self.bytes.len() - self.pos;
        if left < magic.len() || &self.bytes[self.pos..self.pos + magic.len()] != magic {
            return Err(CodecError::BadMagic { expected });
        }
        self.pos += magic.len();
        Ok(())
    }
    /// Reads a file header: the magic bytes of `kind` (e.g. "smirl SAC checkpoint"), then a
    /// format version that must be `version`.
    pub fn header(
        &mut self,
        magic: &[u8],
        kind: &'static str,
        version: u32,
    ) -> Result<(), CodecError> {
        self.magic(magic, kind)?;
        let found = self.u32("version")?;
        if found != version {
            return Err(CodecError::Version {
                what: kind,
                found,
                supported: version,
            });
        }
        Ok(())
    }
    pub fn u8(&mut self, what: &'static str) -> Result<u8, CodecError> {
        Ok(self.take(1, what)?[0])
    }
    pub fn u32(&mut self, what: &'static str) -> Result<u32, CodecError> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }
    pub fn u64(&mut self, what: &'static str) -> Result<u64, CodecError> {
        Ok(u64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
    pub fn u128(&mut self, what: &'static str) -> Result<u128, CodecError> {
        Ok(u128::from_le_bytes(
            self.take(16, what)?.try_into().unwrap(),
        ))
    }
    pub fn f32(&mut self, what: &'static str) -> Result<f32, CodecError> {
        Ok(f32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }
    pub fn usize(&mut self, what: &'static str) -> Result<usize, CodecError> {
        let v = self.u64(what)?;
        usize::try_from(v).map_err(|_| CodecError::Invalid {
            what,
            problem: format!("length {v} does not fit in memory"),
        })
    }
    pub fn blob(&mut self, what: &'static str) -> Result<&'a [u8], CodecError> {
        let n = self.usize(what)?;
        self.take(n, what)
    }
    pub fn string(&mut self, what: &'static str) -> Result<String, CodecError> {
        let b = self.blob(what)?;
        String::from_utf8(b.to_vec()).map_err(|_| CodecError::Invalid {
            what,
            problem: "not UTF-8".into(),
        })
    }
    /// Reads a length-prefixed `f32` slice into `out`, which must have the stored length.
    pub fn f32s_into(&mut self, out: &mut [f32], what: &'static str) -> Result<(), CodecError> {
        let n = self.usize(what)?;
        if n != out.len() {
            return Err(CodecError::Invalid {
                what,
                problem: format!("{n} values stored, {} expected", out.len()),
            });
        }
        let b = self.take(n * 4, what)?;
        for (o, c) in out.iter_mut().zip(b.chunks_exact(4)) {
            *o = f32::from_le_bytes(c.try_into().unwrap());
        }
        Ok(())
    }
    pub fn f32s(&mut self, what: &'static str) -> Result<Vec<f32>, CodecError> {
        let n = self.usize(what)?;
        let b = self.take(n.saturating_mul(4), what)?;
        Ok(b.chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect())
    }
    pub fn u32s(&mut self, what: &'static str) -> Result<Vec<u32>, CodecError> {
        let n = self.usize(what)?;
        let b = self.take(n.saturating_mul(4), what)?;
        Ok(b.chunks_exact(4)
            .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
            .collect())
    }
    /// Fails unless every byte was consumed.
    pub fn finish(&self) -> Result<(), CodecError> {
        match self.bytes.len() - self.pos {
            0 => Ok(()),
            n => Err(CodecError::Trailing(n)),
        }
    }
}
