//! Reading an input file whole, with a limit on its size checked before its content is read
//! (and again while reading, for files whose size the file system does not know, such as
//! `/dev/zero`): a file given by a user must not become an unbounded allocation.

use std::io::Read;
use std::path::Path;

/// Largest text file the program writes and reads back (job records, learned rewards, expert
/// curves): 64 MiB; the project's are under 1 MiB (a job record of 20 iterations: 10 kB).
pub const MAX_DATA_FILE_BYTES: u64 = 64 << 20;

/// The bytes of the file at `path`, at most `limit` of them; a larger file is an
/// `InvalidData` error naming the limit.
pub fn read_bytes(path: &Path, limit: u64) -> std::io::Result<Vec<u8>> {
    let file = std::fs::File::open(path)?;
    let too_big = || {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("the file is larger than the limit of {limit} bytes"),
        )
    };
    let declared = file.metadata()?.len();
    if declared > limit {
        return Err(too_big());
    }
    let mut bytes = Vec::with_capacity(declared as usize);
    file.take(limit.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_big());
    }
    Ok(bytes)
}

/// [`read_bytes`] of a UTF-8 text file.
pub fn read_text(path: &Path, limit: u64) -> std::io::Result<String> {
    String::from_utf8(read_bytes(path, limit)?).map_err(|_| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            "stream did not contain valid UTF-8",
        )
    })
}
