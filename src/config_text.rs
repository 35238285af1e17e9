//! Text input files (configs, reward machines): a size limit checked before reading, and
//! the line of a TOML key, so that an error about a value names the line it is on.

use std::path::Path;

/// Largest text input file read (configs, reward machines): 1 MiB, far above any real one.
pub const MAX_TEXT_FILE_BYTES: u64 = 1 << 20;

/// Reads a UTF-8 text file of at most [`MAX_TEXT_FILE_BYTES`]; a larger one is an
/// `InvalidData` error naming the limit (checked before its content is read).
pub fn read_text_file(path: &Path) -> std::io::Result<String> {
    crate::input_file::read_text(path, MAX_TEXT_FILE_BYTES)
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
/// `"env.cancel.latest_step"`: table path, then key) in a TOML document: on its own line
/// under its `[table]` header, as a dotted key (`sac.batch_size = 3`, or `cancel.latest_step`
/// under `[env]`), or inside an inline table (`sac = { batch_size = 3 }`). When the key is
/// absent, the line of the deepest table on its path written with a header or braces; `None`
/// when there is none, or when `text` is not TOML.
pub fn key_line(text: &str, dotted: &str) -> Option<usize> {
    // Read from the parsed document's spans, so that text inside strings (a `[x]` or `k = v`
    // in a multi-line string) is never taken for a header or a key.
    let doc = toml_edit::ImDocument::parse(text).ok()?;
    let line = |at: usize| text[..at.min(text.len())].matches('\n').count() + 1;
    let path = path_of(dotted);
    let mut table: &dyn toml_edit::TableLike = doc.as_table();
    // The line of the deepest table on the way that has one of its own: a `[table]` header
    // or an inline table's `{` (a dotted key's table has none).
    let mut enclosing = None;
    for (depth, part) in path.iter().enumerate() {
        let Some((key, item)) = table.get_key_value(part) else {
            return enclosing;
        };
        if depth + 1 == path.len() {
            return key.span().map(|s| line(s.start)).or(enclosing);
        }
        let own = match item {
            toml_edit::Item::Table(t) => t.span(),
            toml_edit::Item::Value(toml_edit::Value::InlineTable(t)) => t.span(),
            _ => None,
        };
        if let Some(span) = own {
            enclosing = Some(line(span.start));
        }
        match item.as_table_like() {
            Some(next) => table = next,
            None => return enclosing,
        }
    }
    enclosing
}

/// The parts of a TOML key or table name (`env . "cancel"` → `["env", "cancel"]`; dots inside
/// quotes are not expected in this project's keys).
fn path_of(key: &str) -> Vec<String> {
    key.split('.')
        .map(|part| part.trim().trim_matches('"').trim_matches('\'').to_string())
        .filter(|part| !part.is_empty())
        .collect()
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

    #[test]
    fn finds_dotted_keys_and_inline_tables() {
        let text = "sac.batch_size = 3\nenv = { max_steps = 4, cancel = { latest_step = 5 } }\n\
                    [schedule]\nfkl.sac.lr = 0.1\n[ \"schedule\" . js ]\nlr = 2\n";
        assert_eq!(key_line(text, "sac.batch_size"), Some(1));
        assert_eq!(key_line(text, "env.max_steps"), Some(2));
        assert_eq!(key_line(text, "env.cancel.latest_step"), Some(2));
        assert_eq!(key_line(text, "schedule.fkl.sac.lr"), Some(4));
        assert_eq!(key_line(text, "schedule.js.lr"), Some(6));
        // Absent keys: the line of the table they would be in.
        assert_eq!(key_line(text, "schedule.rkl.lr"), Some(3));
        assert_eq!(key_line(text, "schedule.js.tau"), Some(5));
        assert_eq!(key_line(text, "sac.lr"), None);
    }

    #[test]
    fn text_inside_strings_is_neither_a_header_nor_a_key() {
        let text = "note = \"\"\"\n[sac]\nlr = 9\n\"\"\"\nlr = 1 # [env]\n[env]\nname = \"a # b = 2\"\nb = 3\n";
        assert_eq!(key_line(text, "lr"), Some(5));
        assert_eq!(key_line(text, "sac.lr"), None);
        assert_eq!(key_line(text, "env.b"), Some(8));
        assert_eq!(key_line(text, "env.c"), Some(6));
    }
}
