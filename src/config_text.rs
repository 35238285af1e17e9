//! Text input files (configs, reward machines): a size limit checked before reading, and
//! the line of a TOML key, so that an error about a value names the line it is on.

use std::io::Read;
use std::path::Path;

/// Largest text input file read (configs, reward machines): 1 MiB, far above any real one.
pub const MAX_TEXT_FILE_BYTES: u64 = 1 << 20;

/// Reads a UTF-8 text file of at most [`MAX_TEXT_FILE_BYTES`]; a larger one is an
/// `InvalidData` error naming the limit (checked before its content is read).
pub fn read_text_file(path: &Path) -> std::io::Result<String> {
    let file = std::fs::File::open(path)?;
    let too_big = || {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("the file is larger than the limit of {MAX_TEXT_FILE_BYTES} bytes"),
        )
    };
    if file.metadata()?.len() > MAX_TEXT_FILE_BYTES {
        return Err(too_big());
    }
    let mut text = String::new();
    file.take(MAX_TEXT_FILE_BYTES + 1)
        .read_to_string(&mut text)?;
    if text.len() as u64 > MAX_TEXT_FILE_BYTES {
        return Err(too_big());
    }
    Ok(text)
}

/// The message of a TOML parse error of `text`, led by its line and, when the error is about
/// a value, the key it belongs to (`line 3: field `kde_bandwidth`: invalid type ...`). A
/// missing key has no line of its own (the error spans the whole document): none is given.
pub fn toml_error_message(text: &str, e: &toml::de::Error) -> String {
    let message = e.message().trim().to_string();
    let Some(span) = e.span().filter(|_| !message.starts_with("missing field")) else {
        return message;
    };
    let line = text[..span.start.min(text.len())].matches('\n').count() + 1;
    // Name the field whose value is wrong (the span points at the value).
    let key = text
        .lines()
        .nth(line - 1)
        .and_then(|l| l.split_once('='))
        .map(|(k, _)| k.trim().to_string())
        .filter(|k| !k.is_empty() && !message.contains(k.as_str()));
    match key {
        Some(k) => format!("line {line}: field `{k}`: {message}"),
        None => format!("line {line}: {message}"),
    }
}

/// The 1-based line of the key `dotted` (`"lrm_steps"`, `"sac.batch_size"`,
/// `"env.cancel.latest_step"`: table path, then key) in a TOML document written with one
/// `[table]` header per table; the table's header line when the key is absent (its value
/// is a default), `None` when neither is there.
pub fn key_line(text: &str, dotted: &str) -> Option<usize> {
    let (table, key) = match dotted.rsplit_once('.') {
        Some((t, k)) => (t, k),
        None => ("", dotted),
    };
    let mut current = String::new();
    let mut header = None;
    for (i, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim();
        if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            current = name.trim().to_string();
            if current == dotted {
                // The key names a table (`[schedule.fkl]`): its header.
                return Some(i + 1);
            }
            if current == table {
                header = Some(i + 1);
            }
            continue;
        }
        if current != table {
            continue;
        }
        if let Some((k, _)) = line.split_once('=') {
            if k.trim().trim_matches('"') == key {
                return Some(i + 1);
            }
        }
    }
    header
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_keys_in_their_tables() {
        let text = "a = 1\n# b = 2\n[sac]\nbatch_size = 3\n\n[env]\nmax_steps = 4\n[env.cancel]\n\"latest_step\" = 5 # x\n";
        assert_eq!(key_line(text, "a"), Some(1));
        assert_eq!(key_line(text, "b"), None);
        assert_eq!(key_line(text, "sac.batch_size"), Some(4));
        assert_eq!(key_line(text, "sac.lr"), Some(3));
        assert_eq!(key_line(text, "env.max_steps"), Some(7));
        assert_eq!(key_line(text, "env.cancel.latest_step"), Some(9));
        assert_eq!(key_line(text, "env.cancel"), Some(8));
        assert_eq!(key_line(text, "batch_size"), None);
    }
}
