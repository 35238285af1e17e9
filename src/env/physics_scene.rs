//! The physics of a scene: its MJCF text without the bodies that only mark regions.
//!
//! A movable region of the built-in scene is a mocap body: a body of the world with no degrees
//! of freedom that the environment places at reset. The labels come from the environment's
//! own region positions, never from MuJoCo, and nothing collides, so such a body changes no
//! joint of the arm; yet MuJoCo's kinematics, composite inertia and velocity passes visit every
//! body at every RK4 stage, and the four balls cost a third of a step
//! (`experiments/env/mocap_cost.txt`). The physics model is the scene with those bodies cut
//! out of the text; the scene itself stays what logs record and what rendering draws.
//!
//! The cut is textual on purpose: MuJoCo 2.2.2 has no model-editing API, and the scene may be
//! a user's file with defaults and classes the cut must leave alone. Only a `<body>` element
//! that is a direct child of `<worldbody>`, has `mocap="true"`, is named in the cut list and
//! holds no `<body>`, `<joint>` or `<freejoint>` is removed; anything else is refused rather
//! than guessed at.

/// Why a scene's text cannot be cut.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SceneCutError {
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
    #[error("body '{0}' is not a mocap body directly under <worldbody>")]
    NotAWorldMocapBody(String),
    #[error("body '{0}' holds a body or a joint, so it is part of the physics")]
    HoldsPhysics(String),
    #[error("body '{0}' is not in the scene")]
    Missing(String),
}

/// One tag of the text: its kind, element name, attributes and byte range.
#[derive(Debug)]
struct Tag<'a> {
    kind: TagKind,
    name: &'a str,
    attributes: &'a str,
    start: usize,
    end: usize,
}

#[derive(Debug, PartialEq, Eq)]
enum TagKind {
    Open,
    Close,
    SelfClosing,
}

/// The element tags of `xml` in order, skipping comments, processing instructions,
/// declarations and CDATA sections.
fn tags(xml: &str) -> Result<Vec<Tag<'_>>, SceneCutError> {
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
                .ok_or(SceneCutError::Unclosed { at: start, what })?;
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
        let end = end.ok_or(SceneCutError::Unclosed {
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
fn attribute<'a>(attributes: &'a str, key: &str) -> Option<&'a str> {
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

/// `xml` without the mocap bodies named in `bodies` (each a direct child of `<worldbody>`
/// holding no body and no joint); the rest of the text byte for byte.
pub fn without_mocap_bodies(xml: &str, bodies: &[&str]) -> Result<String, SceneCutError> {
    let tags = tags(xml)?;
    // Open elements: (name, index of the tag that opened it).
    let mut open: Vec<(&str, usize)> = Vec::new();
    let mut cuts: Vec<(usize, usize, &str)> = Vec::new();
    let mut found = vec![false; bodies.len()];
    for (t, tag) in tags.iter().enumerate() {
        match tag.kind {
            TagKind::Open | TagKind::SelfClosing => {
                let named = (tag.name == "body")
                    .then(|| attribute(tag.attributes, "name"))
                    .flatten()
                    .and_then(|n| bodies.iter().position(|b| *b == n));
                if let Some(k) = named {
                    let parent = open.last().map(|(name, _)| *name);
                    if parent != Some("worldbody")
                        || attribute(tag.attributes, "mocap") != Some("true")
                    {
                        return Err(SceneCutError::NotAWorldMocapBody(bodies[k].into()));
                    }
                    found[k] = true;
                    if tag.kind == TagKind::SelfClosing {
                        cuts.push((tag.start, tag.end, bodies[k]));
                    }
                }
                if tag.kind == TagKind::Open {
                    open.push((tag.name, t));
                }
            }
            TagKind::Close => {
                let Some((name, opened)) = open.pop() else {
                    return Err(SceneCutError::Unopened {
                        at: tag.start,
                        got: tag.name.into(),
                    });
                };
                if name != tag.name {
                    return Err(SceneCutError::Mismatched {
                        at: tag.start,
                        got: tag.name.into(),
                        expected: name.into(),
                    });
                }
                let first = &tags[opened];
                let cut_name = (name == "body")
                    .then(|| attribute(first.attributes, "name"))
                    .flatten()
                    .and_then(|n| bodies.iter().find(|b| **b == n));
                if let Some(&body) = cut_name {
                    let holds_physics = tags[opened + 1..t]
                        .iter()
                        .any(|inner| matches!(inner.name, "body" | "joint" | "freejoint"));
                    if holds_physics {
                        return Err(SceneCutError::HoldsPhysics(body.into()));
                    }
                    cuts.push((first.start, tag.end, body));
                }
            }
        }
    }
    if let Some((name, opened)) = open.last() {
        return Err(SceneCutError::Unclosed {
            at: tags[*opened].start,
            what: if *name == "body" { "body" } else { "element" },
        });
    }
    if let Some(k) = found.iter().position(|f| !f) {
        return Err(SceneCutError::Missing(bodies[k].into()));
    }
    cuts.sort_by_key(|c| c.0);
    let mut out = String::with_capacity(xml.len());
    let mut from = 0;
    for (start, end, _) in cuts {
        out.push_str(&xml[from..start]);
        from = end;
    }
    out.push_str(&xml[from..]);
    Ok(out)
}
