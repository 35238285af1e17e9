//! User input quoted in error messages, readable whatever it holds: invisible characters are
//! named (`<NUL>`, `<U+FEFF>` for a byte-order mark) instead of echoed raw, long text is cut
//! to [`MAX_QUOTED_CHARS`] characters with its length given, and a number prints in at most
//! a few dozen characters (`1e300`, not 301 digits).

/// Most characters of quoted input an error message shows.
pub const MAX_QUOTED_CHARS: usize = 60;

/// The name of a character that would print as nothing or break the line, if it is one.
fn invisible_name(c: char) -> Option<String> {
    let named = match c {
        '\0' => Some("NUL"),
        '\t' => Some("TAB"),
        '\r' => Some("CR"),
        '\n' => Some("LF"),
        _ => None,
    };
    if let Some(n) = named {
        return Some(n.to_string());
    }
    let format_char = matches!(
        c,
        '\u{00ad}'
            | '\u{200b}'..='\u{200f}'
            | '\u{2028}'..='\u{202e}'
            | '\u{2060}'..='\u{2064}'
            | '\u{feff}'
    );
    (c.is_control() || format_char).then(|| format!("U+{:04X}", c as u32))
}

/// `text` as an error message quotes it (without the quotes): invisible characters named
/// as `<NAME>`, cut after [`MAX_QUOTED_CHARS`] characters with `… (N characters)`.
pub fn text(text: &str) -> String {
    let mut out = String::new();
    let total = text.chars().count();
    for c in text.chars().take(MAX_QUOTED_CHARS) {
        match invisible_name(c) {
            Some(name) => {
                out.push('<');
                out.push_str(&name);
                out.push('>');
            }
            None => out.push(c),
        }
    }
    if total > MAX_QUOTED_CHARS {
        out.push_str(&format!("… ({total} characters)"));
    }
    out
}

/// `x` as an error message prints it: as Rust writes it when that is short (`0.3`, `-2`),
/// else in exponent form (`1e300`).
pub fn number(x: f64) -> String {
    let plain = x.to_string();
    if plain.len() <= 24 {
        plain
    } else {
        format!("{x:e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invisible_characters_are_named_and_long_text_is_cut() {
        assert_eq!(text("\u{feff}states: 3"), "<U+FEFF>states: 3");
        assert_eq!(text("a\0b"), "a<NUL>b");
        let long = "r|".repeat(2000);
        let quoted = text(&long);
        assert!(quoted.ends_with("… (4000 characters)"), "{quoted}");
        assert!(quoted.chars().count() < 100);
        assert_eq!(text("plain"), "plain");
    }

    #[test]
    fn numbers_stay_short() {
        assert_eq!(number(0.25), "0.25");
        assert_eq!(number(1e300), "1e300");
        assert_eq!(number(-1e-300), "-1e-300");
        assert_eq!(number(f64::NAN), "NaN");
    }
}
