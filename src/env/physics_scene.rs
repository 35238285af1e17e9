//! The physics of a scene: its MJCF text without the bodies that only mark regions and the
//! geoms that only draw the arena.
//!
//! A movable region of the built-in scene is a mocap body: a body of the world with no degrees
//! of freedom that the environment places at reset. The labels come from the environment's
//! own region positions, never from MuJoCo, and nothing collides, so such a body changes no
//! joint of the arm; yet MuJoCo's kinematics, composite inertia and velocity passes visit every
//! body at every RK4 stage, and the four balls cost a third of a step
//! (`experiments/env/mocap_cost.txt`). The world's own geoms (floor, walls, the arm's base) are
//! placed again at every stage as well, and move and weigh nothing. The physics model is the
//! scene with both cut out of the text; the scene itself stays what logs record and what
//! rendering draws.
//!
//! The cut is textual on purpose: MuJoCo 2.2.2 has no model-editing API, and the scene may be
//! a user's file with defaults and classes the cut must leave alone. Only a `<body>` element
//! that is a direct child of `<worldbody>`, has `mocap="true"`, is named in the cut list and
//! holds no `<body>`, `<joint>` or `<freejoint>` is removed, and only `<geom>` elements that
//! are direct children of `<worldbody>`; anything else is refused rather than guessed at.
//! [`physics_model`] cuts only where the cut provably leaves the arm alone (no geom it removes
//! can touch a geom of another body, the cut text compiles to the same joints and actuators)
//! and otherwise cuts less or steps the scene itself: a scene it cannot cut is slower, never
//! different.

use super::layout::{Anchor, LoadedScene, Scene, TaskLayout};
use super::placement::Placement;
use super::scene_files::{compile_in_memory, SceneCompileError};
use super::scene_xml::{attribute, tags, Tag, TagKind, XmlSyntaxError};
use crate::mujoco::Model;

/// Why a scene's text cannot be cut.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SceneCutError {
    #[error(transparent)]
    Syntax(#[from] XmlSyntaxError),
    #[error("body '{0}' is not a mocap body directly under <worldbody>")]
    NotAWorldMocapBody(String),
    #[error("body '{0}' holds a body or a joint, so it is part of the physics")]
    HoldsPhysics(String),
    #[error("body '{0}' is not in the scene")]
    Missing(String),
}

/// One element of the text: the tags that open and close it (the same tag when it closes
/// itself) and the name of the element it sits in.
struct Element<'a> {
    open: usize,
    close: usize,
    parent: Option<&'a str>,
}

/// The elements of `tags`, each with its parent, after checking that every tag is closed by
/// the tag that matches it.
fn elements<'a>(tags: &[Tag<'a>]) -> Result<Vec<Element<'a>>, XmlSyntaxError> {
    // Open elements: (name, index of the tag that opened it).
    let mut open: Vec<(&str, usize)> = Vec::new();
    let mut out = Vec::new();
    for (t, tag) in tags.iter().enumerate() {
        let parent = open.last().map(|(name, _)| *name);
        match tag.kind {
            TagKind::SelfClosing => out.push(Element {
                open: t,
                close: t,
                parent,
            }),
            TagKind::Open => open.push((tag.name, t)),
            TagKind::Close => {
                let Some((name, opened)) = open.pop() else {
                    return Err(XmlSyntaxError::Unopened {
                        at: tag.start,
                        got: tag.name.into(),
                    });
                };
                if name != tag.name {
                    return Err(XmlSyntaxError::Mismatched {
                        at: tag.start,
                        got: tag.name.into(),
                        expected: name.into(),
                    });
                }
                out.push(Element {
                    open: opened,
                    close: t,
                    parent: open.last().map(|(name, _)| *name),
                });
            }
        }
    }
    if let Some((name, opened)) = open.last() {
        return Err(XmlSyntaxError::Unclosed {
            at: tags[*opened].start,
            what: if *name == "body" { "body" } else { "element" },
        });
    }
    out.sort_by_key(|e| e.open);
    Ok(out)
}

/// `xml` without the byte ranges `cuts` (disjoint).
fn remove(xml: &str, mut cuts: Vec<(usize, usize)>) -> String {
    cuts.sort_unstable();
    let mut out = String::with_capacity(xml.len());
    let mut from = 0;
    for (start, end) in cuts {
        out.push_str(&xml[from..start]);
        from = end;
    }
    out.push_str(&xml[from..]);
    out
}

/// `xml` without the mocap bodies named in `bodies` (each a direct child of `<worldbody>`
/// holding no body and no joint); the rest of the text byte for byte.
pub fn without_mocap_bodies(xml: &str, bodies: &[&str]) -> Result<String, SceneCutError> {
    let tags = tags(xml)?;
    let mut cuts = Vec::new();
    let mut found = vec![false; bodies.len()];
    for element in elements(&tags)? {
        let first = &tags[element.open];
        let named = (first.name == "body")
            .then(|| attribute(first.attributes, "name"))
            .flatten()
            .and_then(|n| bodies.iter().position(|b| *b == n));
        let Some(k) = named else { continue };
        if element.parent != Some("worldbody")
            || attribute(first.attributes, "mocap") != Some("true")
        {
            return Err(SceneCutError::NotAWorldMocapBody(bodies[k].into()));
        }
        // A self-closing body (open == close) holds nothing.
        let holds_physics = (tags.get(element.open + 1..element.close))
            .unwrap_or_default()
            .iter()
            .any(|inner| matches!(inner.name, "body" | "joint" | "freejoint"));
        if holds_physics {
            return Err(SceneCutError::HoldsPhysics(bodies[k].into()));
        }
        found[k] = true;
        cuts.push((first.start, tags[element.close].end));
    }
    if let Some(k) = found.iter().position(|f| !f) {
        return Err(SceneCutError::Missing(bodies[k].into()));
    }
    Ok(remove(xml, cuts))
}

/// `xml` without the geoms that are direct children of `<worldbody>` (the arena's floor and
/// walls in the built-in scene); the rest of the text byte for byte. A geom of the world body
/// moves nothing and weighs nothing: it acts on the arm only through a collision, which
/// [`physics_model`] rules out before it cuts.
pub fn without_world_geoms(xml: &str) -> Result<String, SceneCutError> {
    let tags = tags(xml)?;
    let cuts = (elements(&tags)?.iter())
        .filter(|e| tags[e.open].name == "geom" && e.parent == Some("worldbody"))
        .map(|e| (tags[e.open].start, tags[e.close].end))
        .collect();
    Ok(remove(xml, cuts))
}

/// Why the model of a task's scene cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum SceneModelError {
    #[error(transparent)]
    Compile(#[from] SceneCompileError),
    #[error("the layout of scene {scene} holds none of its bytes: an environment steps the scene as its task loaded it (a layout read back from a record names its scene only)")]
    NotLoaded { scene: String },
}

/// The model of a task's scene: the built-in scene, or a file scene compiled from memory
/// from the bytes its task loaded ([`TaskLayout::loaded`]), as the task was checked on it and
/// as its logs rebuild it. The files are not read again: one edited since the task loaded
/// would train on bytes other than those its expert key and its logs record.
pub fn scene_model(layout: &TaskLayout) -> Result<Model, SceneModelError> {
    Ok(match &layout.scene {
        Scene::Builtin => {
            Model::from_xml_str(crate::assets::REACHER_XML, crate::assets::REACHER_XML_NAME)
                .map_err(SceneCompileError::from)?
        }
        Scene::File(_) => {
            let loaded = loaded(layout)?;
            compile_in_memory(&loaded.text, &loaded.files, &layout.scene.to_string())?
        }
    })
}

/// The bytes a file scene's task loaded.
fn loaded(layout: &TaskLayout) -> Result<&LoadedScene, SceneModelError> {
    layout
        .loaded
        .as_ref()
        .ok_or_else(|| SceneModelError::NotLoaded {
            scene: layout.scene.to_string(),
        })
}

/// The model an environment steps for a task, and which regions' bodies it leaves out.
pub struct PhysicsModel {
    pub model: Model,
    /// Per region, in label-bit order: its body is not in `model`.
    pub left_out: Vec<bool>,
}

/// The task's scene without the mocap bodies of its movable regions and without the world's
/// own geoms, or with as much of that cut as leaves the arm's physics provably alone (see the
/// module documentation): the scene itself when nothing can be cut.
/// Errors are the scene's own (it does not load), or a file scene's layout without its bytes.
pub fn physics_model(layout: &TaskLayout) -> Result<PhysicsModel, SceneModelError> {
    let scene = scene_model(layout)?;
    let left_out: Vec<bool> = (layout.regions.iter())
        .map(|region| match (&region.anchor, region.movable) {
            (Anchor::Body(body), true) => scene
                .id(crate::mujoco::ObjectKind::Body, body)
                .is_ok_and(|id| {
                    matches!(Placement::find(&scene, body), Some(Placement::Mocap { .. }))
                        && !touches_anything(&scene, id)
                }),
            _ => false,
        })
        .collect();
    let mut bodies: Vec<&str> = (layout.regions.iter().zip(&left_out))
        .filter(|(_, cut)| **cut)
        .map(|(region, _)| region.anchor.name())
        .collect();
    bodies.sort_unstable();
    bodies.dedup();
    // The world's geoms go too when none of them can collide. A cut text that does not
    // compile (a sensor, tendon or contact pair names a geom) is retried with the bodies alone.
    let world_geoms =
        (0..scene.ngeom()).any(|g| scene.geom_body(g) == 0) && !touches_anything(&scene, 0);
    let attempts = [(bodies.as_slice(), world_geoms), (bodies.as_slice(), false)];
    let cut = (attempts.iter())
        .filter(|(bodies, geoms)| !bodies.is_empty() || *geoms)
        .find_map(|(bodies, geoms)| {
            cut_model(layout, bodies, *geoms).filter(|model| same_arm(&scene, model))
        });
    Ok(match cut {
        Some(model) => PhysicsModel { model, left_out },
        None => PhysicsModel {
            model: scene,
            left_out: vec![false; layout.n_regions()],
        },
    })
}

/// The scene compiled without `bodies` (and without the world's geoms when `world_geoms`),
/// when its text can be cut and the cut text compiles; a file scene's text and files are
/// those its task loaded, as in [`scene_model`].
fn cut_model(layout: &TaskLayout, bodies: &[&str], world_geoms: bool) -> Option<Model> {
    let cut = |text: &str| {
        let text = without_mocap_bodies(text, bodies).ok()?;
        if world_geoms {
            without_world_geoms(&text).ok()
        } else {
            Some(text)
        }
    };
    match &layout.scene {
        Scene::Builtin => {
            let text = cut(crate::assets::REACHER_XML)?;
            Model::from_xml_str(&text, crate::assets::REACHER_XML_NAME).ok()
        }
        Scene::File(_) => {
            let loaded = loaded(layout).ok()?;
            let text = cut(&loaded.text)?;
            compile_in_memory(&text, &loaded.files, &layout.scene.to_string()).ok()
        }
    }
}

/// Whether a geom of body `id` can collide with any geom of another body (MuJoCo's test: one
/// geom's contype shares a bit with the other's conaffinity).
fn touches_anything(scene: &Model, id: usize) -> bool {
    let geoms = 0..scene.ngeom();
    geoms
        .clone()
        .filter(|&g| scene.geom_body(g) == id)
        .any(|g| {
            let (type_a, affinity_a) = scene.geom_collision_masks(g);
            geoms
                .clone()
                .filter(|&h| scene.geom_body(h) != id)
                .any(|h| {
                    let (type_b, affinity_b) = scene.geom_collision_masks(h);
                    type_a & affinity_b != 0 || type_b & affinity_a != 0
                })
        })
}

/// The cut model keeps every joint, degree of freedom and actuator of the scene.
fn same_arm(scene: &Model, cut: &Model) -> bool {
    (
        scene.nq(),
        scene.nv(),
        scene.nu(),
        scene.njnt(),
        scene.timestep(),
    ) == (cut.nq(), cut.nv(), cut.nu(), cut.njnt(), cut.timestep())
}
