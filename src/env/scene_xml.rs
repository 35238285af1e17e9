//! The element tags of an MJCF text, read without an XML library: what the scene walker
//! (`scene_files`) and the physics cut (`physics_scene`) both need, and no more — tags in order
//! with their byte ranges, an attribute's value, and the syntax errors that stop either.

/// Largest scene file read as text (a task file's scene, or the text cut from it).
pub const MAX_SCENE_BYTES: u64 = crate::config_text::MAX_TEXT_FILE_BYTES * 16;

/// Why the tags of a text do not nest.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum XmlSyntaxError {
    #[error("byte {at}: {what} is not closed")]
    Unclosed { at: usize, what: &'static str },
    #[error("byte {at}: closing tag </{got}> where </{expected}> was open")]
    Mismatched {
        at: usize,
        got: String,
        expected: String,
    },
    #[error("byte {at}: closing tag </{got}> with no element open")]
    Unopened { at: usize, got: String },
}

/// One tag of the text: its kind, element name, attributes and byte range.
#[derive(Debug)]
pub(crate) struct Tag<'a> {
    pub(crate) kind: TagKind,
    pub(crate) name: &'a str,
    pub(crate) attributes: &'a str,
    pub(crate) start: usize,
    pub(crate) end: usize,
}

#[derive(Debug, PartialEq, Eq)]
pub(crate) enum TagKind {
    Open,
    Close,
    SelfClosing,
}

/// The element tags of `xml` in order, skipping comments, processing instructions,
/// declarations and CDATA sections.
pub(crate) fn tags(xml: &str) -> Result<Vec<Tag<'_>>, XmlSyntaxError> {
    let bytes = xml.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while let Some(offset) = xml[i..].find('<') {
        let start = i + offset;
        let rest = &xml[start..];
        let skip = [
            ("<!--", "-->", "comment"),
            ("<![CDATA[", "]]>", "CDATA section"),
            ("<?", "?>", "processing instruction"),
            ("<!", ">", "declaration"),
        ]
        .into_iter()
        .find(|(open, _, _)| rest.starts_with(open));
        if let Some((open, close, what)) = skip {
            let end = rest[open.len()..]
                .find(close)
                .ok_or(XmlSyntaxError::Unclosed { at: start, what })?;
            i = start + open.len() + end + close.len();
            continue;
        }
        // The tag ends at the first '>' outside a quoted attribute value.
        let mut quote = None;
        let mut end = None;
        for (k, &b) in bytes[start + 1..].iter().enumerate() {
            match (quote, b) {
                (None, b'"' | b'\'') => quote = Some(b),
                (Some(q), _) if b == q => quote = None,
                (None, b'>') => {
                    end = Some(start + 1 + k + 1);
                    break;
                }
                _ => {}
            }
        }
        let end = end.ok_or(XmlSyntaxError::Unclosed {
            at: start,
            what: "tag",
        })?;
        let inner = &xml[start + 1..end - 1];
        let (kind, inner) = if let Some(name) = inner.strip_prefix('/') {
            (TagKind::Close, name)
        } else if let Some(open) = inner.strip_suffix('/') {
            (TagKind::SelfClosing, open)
        } else {
            (TagKind::Open, inner)
        };
        let inner = inner.trim();
        let name_end = inner
            .find(|c: char| c.is_ascii_whitespace())
            .unwrap_or(inner.len());
        out.push(Tag {
            kind,
            name: &inner[..name_end],
            attributes: &inner[name_end..],
            start,
            end,
        });
        i = end;
    }
    Ok(out)
}

/// The value of attribute `key` in a tag's attribute text.
pub(crate) fn attribute<'a>(attributes: &'a str, key: &str) -> Option<&'a str> {
    let mut rest = attributes;
    loop {
        rest = rest.trim_start();
        let eq = rest.find('=')?;
        let name = rest[..eq].trim();
        let after = rest[eq + 1..].trim_start();
        let quote = after.chars().next().filter(|c| *c == '"' || *c == '\'')?;
        let close = after[1..].find(quote)?;
        let value = &after[1..1 + close];
        if name == key {
            return Some(value);
        }
        rest = &after[close + 2..];
    }
}
