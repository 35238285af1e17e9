//! The files a scene reads besides its own text, found as MuJoCo 2.2.2 finds them: every file
//! it `<include>`s, however deep, and every mesh, skin, height-field and texture file that its
//! `<asset>` elements name. A task's expert is keyed by them (the content hash of
//! [`super::task_file::Task`]) and logs carry them, so that an edited mesh trains another
//! expert and a log compiles its scene with no file but itself.
//!
//! MuJoCo 2.2.2 resolves the names as strings, and so does this module:
//! - an included file, at any depth, is the main scene file's directory followed by the
//!   include's `file`;
//! - an asset file is its `file` (with `strippath="true"`, the file's last path component)
//!   when that is absolute; otherwise `meshdir` (meshes, skins, height fields) or `texturedir`
//!   (textures) followed by the file when that directory is absolute; otherwise the main scene
//!   file's directory, then that directory, then the file. The compiler applies `meshdir`,
//!   `texturedir` and `strippath` after the whole model is read, so the last `<compiler>` that
//!   sets one holds for every asset. (`assetdir` is MuJoCo 2.3's; 2.2.2 does not know it.)
//! - a texture reads its `file` unless it is `builtin`, and without a `file` its cube faces
//!   (`fileright`, `fileleft`, `fileup`, `filedown`, `filefront`, `fileback`).
//!
//! A scene is an MJCF file: MuJoCo reads a document whose root is named `mujoco`, in any case,
//! as MJCF (its schema then takes the lower case only), and so does this module. A URDF file
//! (root `<robot>`) is refused, since MuJoCo finds the meshes it names by other rules.
//! Names on which MuJoCo 2.2.2 aborts the process (an uncaught C++ exception) are refused:
//! a mesh or skin file whose name, after `strippath`, has fewer than 3 bytes (the compiler
//! takes the last 3 as its type), and a height-field or texture file whose name with its
//! directory has fewer than 4 (the compiler reads the last 4 to tell a PNG file).
//!
//! A scene compiled from memory ([`compile_in_memory`], [`compile_alone`]: a log's, whose text
//! and files may have been crafted, and a task's) is walked by the same rules first, its
//! included files found as MuJoCo finds them (in memory by their last path component, else on
//! disk), so that no text reaches MuJoCo with a name it aborts on.

use super::scene_xml::{attribute, tags, Tag, TagKind, XmlSyntaxError, MAX_SCENE_BYTES};
use crate::mujoco::{in_memory_text_name, vfs_key, MjError, Model, TEXT_ALONE_NAME};
use std::borrow::Cow;
use std::fmt;
use std::path::{Path, PathBuf};

/// Most files a scene may include, directly or through other included files.
pub const MAX_INCLUDED_FILES: usize = 64;
/// Most bytes the files a scene includes may hold together: 64 MiB, so that a log, which
/// carries them with the scene's text and its asset files, stays within what a log reader
/// accepts (`log::reader::MAX_LOGGED_SCENE_BYTES`, asserted when the crate compiles).
pub const MAX_INCLUDED_BYTES: u64 = 64 << 20;
/// Most mesh, skin, height-field and texture files a scene may name.
pub const MAX_ASSET_FILES: usize = 256;
/// Most bytes the mesh, skin, height-field and texture files of a scene may hold together:
/// 64 MiB (MuJoCo 2.2.2 reads a binary STL of at most 200 000 faces, about 10 MB).
pub const MAX_ASSET_BYTES: u64 = 64 << 20;

/// What a file is to the scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneFileKind {
    /// An MJCF file the scene `<include>`s.
    Include,
    /// A mesh, skin, height-field or texture file.
    Asset,
}

/// A file a scene reads, named as the scene names it: relative to the main scene file's
/// directory (`parts/motors.xml`, `meshes/link.stl` for `meshdir="meshes"`), or the absolute
/// path the scene gives.
#[derive(Clone, PartialEq, Eq)]
pub struct SceneFile {
    pub kind: SceneFileKind,
    pub name: String,
    pub bytes: Vec<u8>,
}

// A mesh file's bytes are no reading matter in a message: its name, kind and size are.
impl fmt::Debug for SceneFile {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SceneFile")
            .field("kind", &self.kind)
            .field("name", &self.name)
            .field("bytes", &self.bytes.len())
            .finish()
    }
}

/// A scene file's text and the files it reads: the included files in the order MuJoCo reads
/// them, then the asset files in the order the assembled document names them (each once).
#[derive(Clone, Debug)]
pub struct SceneFiles {
    pub main: Vec<u8>,
    pub files: Vec<SceneFile>,
}

/// Why a scene's files cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum SceneFileError {
    #[error("{what} {file}: cannot read: {error}")]
    Io {
        what: &'static str,
        file: String,
        error: std::io::Error,
    },
    #[error("{file}: {error}")]
    Syntax { file: String, error: XmlSyntaxError },
    #[error("{scene} includes more than {MAX_INCLUDED_FILES} files")]
    TooManyIncludes { scene: String },
    #[error("included file {file}: the files the scene includes hold more than {MAX_INCLUDED_BYTES} bytes together")]
    IncludedBytes { file: String },
    #[error("included file {file}: already included (MuJoCo reads each file once, the scene file among them)")]
    IncludedTwice { file: String },
    #[error(
        "{scene} names more than {MAX_ASSET_FILES} mesh, skin, height-field and texture files"
    )]
    TooManyAssets { scene: String },
    #[error("{what} {file}: the scene's mesh, skin, height-field and texture files hold more than {MAX_ASSET_BYTES} bytes together")]
    AssetBytes { what: &'static str, file: String },
    #[error("{what} {file}: MuJoCo 2.2.2 aborts the process on this name: {rule}")]
    AbortingName {
        what: &'static str,
        file: String,
        rule: String,
    },
    #[error("{scene}: the root element is <{root}>; a task's scene is an MJCF file, whose root is <mujoco> (a URDF file, <robot>, is not taken: MuJoCo finds the meshes it names by rules this reader does not follow, so the expert's key and the logs would miss them)")]
    NotMjcf { scene: String, root: String },
}

impl SceneFileError {
    /// The scene's text could not be read as XML (MuJoCo's own message on it is the better
    /// one).
    pub fn is_syntax(&self) -> bool {
        matches!(self, SceneFileError::Syntax { .. })
    }
}

/// The element that names an asset file.
#[derive(Clone, Copy, PartialEq, Eq)]
enum AssetKind {
    Mesh,
    Skin,
    HeightField,
    Texture,
}

impl AssetKind {
    fn what(self) -> &'static str {
        match self {
            AssetKind::Mesh => "mesh file",
            AssetKind::Skin => "skin file",
            AssetKind::HeightField => "height-field file",
            AssetKind::Texture => "texture file",
        }
    }
}

/// An asset file as an element names it.
struct AssetRef {
    kind: AssetKind,
    file: String,
}

/// An asset file as the compiler resolves it: `name` as the scene names it (with its
/// `meshdir` or `texturedir`), `full` as MuJoCo forms it from the main file's directory.
struct Asset {
    kind: AssetKind,
    name: String,
    full: String,
}

/// What a walk of a scene finds: the files it includes, in the order MuJoCo reads them, each
/// as the scene names it with its bytes, and its asset files (as each element names one, not
/// yet read), none of them with a name MuJoCo 2.2.2 aborts on.
struct Walked<'m> {
    includes: Vec<(String, Cow<'m, [u8]>)>,
    assets: Vec<Asset>,
}

/// The assembled document as it is walked: the elements open around the current tag, across
/// included files, and what was found so far.
struct Walk<'m> {
    /// The main scene file's directory as MuJoCo takes it: up to its last separator.
    dir: String,
    scene: String,
    /// The files MuJoCo holds in memory for the compile, each under its key ([`vfs_key`]):
    /// it looks an included file up there before it reads the disk.
    memory: Vec<(String, &'m [u8])>,
    /// Open elements: name, and whether it is an included file's root (which MuJoCo drops,
    /// its children taking the include's place).
    open: Vec<(String, bool)>,
    /// The names of the open elements that are kept (not an included file's root), outermost
    /// first: what MuJoCo's assembled document has around the current tag.
    kept: Vec<String>,
    /// Every file read so far as MuJoCo names it (directory and file), the scene file first:
    /// MuJoCo refuses to include one twice, comparing the names whatever their case.
    read: Vec<String>,
    included_bytes: u64,
    includes: Vec<(String, Cow<'m, [u8]>)>,
    meshdir: Option<String>,
    texturedir: Option<String>,
    strippath: bool,
    assets: Vec<AssetRef>,
}

/// Reads the scene file at `path` and every file it reads, within [`MAX_INCLUDED_FILES`]
/// included files of at most [`MAX_SCENE_BYTES`] each and [`MAX_INCLUDED_BYTES`] together,
/// and [`MAX_ASSET_FILES`] asset files of at most [`MAX_ASSET_BYTES`] together. Errors name
/// the file.
pub fn read_scene_files(path: &Path) -> Result<SceneFiles, SceneFileError> {
    let scene = path.display().to_string();
    let main = read(path, "scene file", MAX_SCENE_BYTES)?;
    let path_text = path.as_os_str().to_string_lossy();
    let walked = walk(
        &String::from_utf8_lossy(&main),
        &path_text,
        &scene,
        Vec::new(),
    )?;
    let mut files: Vec<SceneFile> = (walked.includes.into_iter())
        .map(|(name, bytes)| SceneFile {
            kind: SceneFileKind::Include,
            name,
            bytes: bytes.into_owned(),
        })
        .collect();
    let mut asset_bytes = 0u64;
    let mut assets = 0;
    for Asset { kind, name, full } in walked.assets {
        if files
            .iter()
            .any(|f| f.kind == SceneFileKind::Asset && f.name == name)
        {
            continue;
        }
        if assets == MAX_ASSET_FILES {
            return Err(SceneFileError::TooManyAssets { scene });
        }
        let what = kind.what();
        let left = MAX_ASSET_BYTES - asset_bytes;
        let over = || SceneFileError::AssetBytes {
            what,
            file: full.clone(),
        };
        let full_path = PathBuf::from(&full);
        // The size the file system reports is checked first, so that a file over the budget
        // is refused by name before it is read.
        if std::fs::metadata(&full_path).is_ok_and(|m| m.len() > left) {
            return Err(over());
        }
        let bytes = read(&full_path, what, left)?;
        asset_bytes += bytes.len() as u64;
        assets += 1;
        files.push(SceneFile {
            kind: SceneFileKind::Asset,
            name,
            bytes,
        });
    }
    Ok(SceneFiles { main, files })
}

/// Walks a scene's `text`, which MuJoCo reads under the name `main` (relative names resolve
/// in its directory), as MuJoCo 2.2.2 assembles it: each file it includes, however deep, is
/// looked up in `memory` by its key and otherwise read from disk at the name MuJoCo forms,
/// within the limits on included files; its asset files are resolved, not read, and a name
/// MuJoCo aborts the process on is refused. `scene` names the text in messages.
fn walk<'m>(
    text: &str,
    main: &str,
    scene: &str,
    memory: Vec<(String, &'m [u8])>,
) -> Result<Walked<'m>, SceneFileError> {
    let mut walk = Walk {
        dir: file_dir(main).to_string(),
        scene: scene.to_string(),
        memory,
        open: Vec::new(),
        kept: Vec::new(),
        read: vec![main.to_string()],
        included_bytes: 0,
        includes: Vec::new(),
        meshdir: None,
        texturedir: None,
        strippath: false,
        assets: Vec::new(),
    };
    walk.text(text, scene, false)?;
    let separated = |dir: &Option<String>| {
        let mut dir = dir.clone().unwrap_or_default();
        if !dir.is_empty() && !dir.ends_with(['/', '\\']) {
            dir.push('/');
        }
        dir
    };
    let (meshdir, texturedir) = (separated(&walk.meshdir), separated(&walk.texturedir));
    let mut assets = Vec::with_capacity(walk.assets.len());
    for asset in &walk.assets {
        let file = if walk.strippath {
            last_component(&asset.file)
        } else {
            &asset.file
        };
        // MuJoCo drops a height field's directory before it asks whether a file is named,
        // the other elements after.
        if asset.kind == AssetKind::HeightField && file.is_empty() {
            continue;
        }
        let sub = match asset.kind {
            AssetKind::Texture => &texturedir,
            _ => &meshdir,
        };
        let (name, full) = if is_absolute(file) {
            (file.to_string(), file.to_string())
        } else if is_absolute(sub) {
            (format!("{sub}{file}"), format!("{sub}{file}"))
        } else {
            (format!("{sub}{file}"), format!("{}{sub}{file}", walk.dir))
        };
        if let Some(rule) = aborting_name(asset.kind, file, &name) {
            return Err(SceneFileError::AbortingName {
                what: asset.kind.what(),
                file: full,
                rule,
            });
        }
        assets.push(Asset {
            kind: asset.kind,
            name,
            full,
        });
    }
    Ok(Walked {
        includes: walk.includes,
        assets,
    })
}

/// Why MuJoCo 2.2.2 would abort the process on an asset file named `file` in its element
/// (after `strippath`), `name` with its directory, if it would. The full name MuJoCo forms
/// (the scene file's directory, then `name`) is never shorter than `name`, so a rule on
/// `name` holds wherever the scene file is, and in the memory a log compiles it from.
fn aborting_name(kind: AssetKind, file: &str, name: &str) -> Option<String> {
    match kind {
        AssetKind::Mesh | AssetKind::Skin if file.len() < 3 => Some(format!(
            "the file name '{file}' has fewer than 3 bytes, and MuJoCo takes its last 3 as \
             the file's type"
        )),
        AssetKind::HeightField | AssetKind::Texture if name.len() < 4 => Some(format!(
            "the name '{name}' has fewer than 4 bytes, and MuJoCo reads its last 4 to tell a \
             PNG file"
        )),
        _ => None,
    }
}

/// Why a scene cannot be compiled from memory.
#[derive(Debug, thiserror::Error)]
pub enum SceneCompileError {
    /// Walked as MuJoCo reads it before MuJoCo compiles it, the scene breaks a rule of
    /// [`read_scene_files`]: it names a file MuJoCo 2.2.2 aborts the process on, includes too
    /// much, or cannot be read.
    #[error("{source_name}: {error}")]
    Scene {
        source_name: String,
        error: SceneFileError,
    },
    #[error(transparent)]
    Compile(#[from] MjError),
}

/// A scene's text compiled with the files it reads held in memory, each under the name the
/// scene gives it ([`Model::from_xml_with_files`]): how a log's scene is compiled, and how a
/// task's scene is compiled for its check and its environment, so that the model a task is
/// checked and trained on is the one its logs rebuild. The text and the files it includes
/// are first walked as MuJoCo reads them ([`check_names`]).
pub fn compile_in_memory(
    text: &str,
    files: &[SceneFile],
    source_name: &str,
) -> Result<Model, SceneCompileError> {
    let main = in_memory_text_name(files.iter().map(|f| f.name.as_str()));
    check_names(text, &main, files, source_name)?;
    let files: Vec<(&str, &[u8])> = (files.iter())
        .map(|f| (f.name.as_str(), f.bytes.as_slice()))
        .collect();
    Ok(Model::from_xml_with_files(text, &files, source_name)?)
}

/// A scene's text compiled alone ([`Model::from_xml_str`]), its relative names resolving in
/// the working directory: how a log that carries no file of its scene is compiled. The text
/// and the files it includes are first walked as MuJoCo reads them ([`check_names`]).
pub fn compile_alone(text: &str, source_name: &str) -> Result<Model, SceneCompileError> {
    check_names(text, TEXT_ALONE_NAME, &[], source_name)?;
    Ok(Model::from_xml_str(text, source_name)?)
}

/// Refuses, before MuJoCo sees it, a scene text that MuJoCo reads under the name `main` with
/// `files` in memory and that breaks a rule of [`read_scene_files`]; above all one that names
/// a file MuJoCo 2.2.2 aborts the process on, which no error message could report. The text
/// and every file it includes are walked as MuJoCo reads them: an included file from memory,
/// found by its key as MuJoCo finds it (the text is there too), or else from disk where MuJoCo
/// looks for it.
fn check_names(
    text: &str,
    main: &str,
    files: &[SceneFile],
    source_name: &str,
) -> Result<(), SceneCompileError> {
    let memory = (files.iter())
        .map(|f| (vfs_key(&f.name), f.bytes.as_slice()))
        .chain([(vfs_key(main), text.as_bytes())])
        .collect();
    walk(text, main, source_name, memory)
        .map(|_| ())
        .map_err(|error| SceneCompileError::Scene {
            source_name: source_name.into(),
            error,
        })
}

/// The bytes of the file at `path`, at most `limit`; errors name it as `what`.
fn read(path: &Path, what: &'static str, limit: u64) -> Result<Vec<u8>, SceneFileError> {
    crate::input_file::read_bytes(path, limit).map_err(|error| SceneFileError::Io {
        what,
        file: path.display().to_string(),
        error,
    })
}

impl Walk<'_> {
    /// Walks the tags of one file's text (`label` names it in messages); an included file's
    /// root element is dropped, as MuJoCo drops it.
    fn text(&mut self, text: &str, label: &str, included: bool) -> Result<(), SceneFileError> {
        let syntax = |error| SceneFileError::Syntax {
            file: label.to_string(),
            error,
        };
        let base = self.open.len();
        for tag in tags(text).map_err(syntax)? {
            let dropped = included && self.open.len() == base;
            // MuJoCo compares the root's name whatever its case, and reads the files of an
            // MJCF document only.
            let root = !included && self.kept.is_empty() && tag.kind != TagKind::Close;
            if root && !tag.name.eq_ignore_ascii_case("mujoco") {
                return Err(SceneFileError::NotMjcf {
                    scene: self.scene.clone(),
                    root: tag.name.to_string(),
                });
            }
            match tag.kind {
                TagKind::Open => {
                    if !dropped {
                        self.element(&tag)?;
                        self.kept.push(tag.name.to_string());
                    }
                    self.open.push((tag.name.to_string(), dropped));
                }
                TagKind::SelfClosing => {
                    if !dropped {
                        self.element(&tag)?;
                    }
                }
                TagKind::Close => {
                    if self.open.len() == base {
                        return Err(syntax(XmlSyntaxError::Unopened {
                            at: tag.start,
                            got: tag.name.into(),
                        }));
                    }
                    let (name, dropped) = self.open.pop().unwrap_or_default();
                    if !dropped {
                        self.kept.pop();
                    }
                    if name != tag.name {
                        return Err(syntax(XmlSyntaxError::Mismatched {
                            at: tag.start,
                            got: tag.name.into(),
                            expected: name,
                        }));
                    }
                }
            }
        }
        if self.open.len() != base {
            return Err(syntax(XmlSyntaxError::Unclosed {
                at: text.len(),
                what: "element",
            }));
        }
        Ok(())
    }

    /// The element a kept tag opens: an include is read and walked in its place; a compiler
    /// directly under the document's root sets the asset directories; an asset names files.
    fn element(&mut self, tag: &Tag) -> Result<(), SceneFileError> {
        let value = |key: &str| attribute(tag.attributes, key).map(unescape);
        // MuJoCo matches `include` whatever its case, the elements it parses exactly.
        if tag.name.eq_ignore_ascii_case("include") {
            let Some(name) = value("file") else {
                return Ok(());
            };
            if self.includes.len() == MAX_INCLUDED_FILES {
                return Err(SceneFileError::TooManyIncludes {
                    scene: self.scene.clone(),
                });
            }
            let full = format!("{}{name}", self.dir);
            if self.read.iter().any(|f| f.eq_ignore_ascii_case(&full)) {
                return Err(SceneFileError::IncludedTwice { file: full });
            }
            let left = MAX_INCLUDED_BYTES - self.included_bytes;
            let over = || SceneFileError::IncludedBytes { file: full.clone() };
            let what = "included file";
            let key = vfs_key(&full);
            let bytes = match self.memory.iter().find(|(k, _)| *k == key) {
                Some(&(_, bytes)) => {
                    let size = bytes.len() as u64;
                    if size > left {
                        return Err(over());
                    }
                    if size > MAX_SCENE_BYTES {
                        return Err(SceneFileError::Io {
                            what,
                            file: full,
                            error: std::io::Error::new(
                                std::io::ErrorKind::InvalidData,
                                format!(
                                    "the file is larger than the limit of {MAX_SCENE_BYTES} bytes"
                                ),
                            ),
                        });
                    }
                    Cow::Borrowed(bytes)
                }
                None => {
                    if std::fs::metadata(&full).is_ok_and(|m| m.len() > left) {
                        return Err(over());
                    }
                    Cow::Owned(read(Path::new(&full), what, left.min(MAX_SCENE_BYTES))?)
                }
            };
            self.included_bytes += bytes.len() as u64;
            self.read.push(full.clone());
            let text = String::from_utf8_lossy(&bytes).into_owned();
            self.includes.push((name.into_owned(), bytes));
            return self.text(&text, &full, true);
        }
        let kept = (self.kept.len(), self.kept.last().map(String::as_str));
        match (tag.name, kept) {
            ("compiler", (1, Some(root))) if root.eq_ignore_ascii_case("mujoco") => {
                if let Some(dir) = value("meshdir") {
                    self.meshdir = Some(dir.into_owned());
                }
                if let Some(dir) = value("texturedir") {
                    self.texturedir = Some(dir.into_owned());
                }
                if let Some(strip) = value("strippath") {
                    self.strippath = strip == "true";
                }
            }
            (element, (_, Some("asset"))) => {
                let mut name = |kind, key: &str| {
                    if let Some(file) = value(key).filter(|f| !f.is_empty()) {
                        self.assets.push(AssetRef {
                            kind,
                            file: file.into_owned(),
                        });
                    }
                };
                match element {
                    "mesh" => name(AssetKind::Mesh, "file"),
                    "skin" => name(AssetKind::Skin, "file"),
                    "hfield" => name(AssetKind::HeightField, "file"),
                    "texture" => {
                        let builtin = value("builtin").is_some_and(|b| b != "none");
                        let file = value("file").is_some_and(|f| !f.is_empty());
                        if builtin {
                            // Made by the compiler: no file is read.
                        } else if file {
                            name(AssetKind::Texture, "file");
                        } else {
                            for face in [
                                "fileright",
                                "fileleft",
                                "fileup",
                                "filedown",
                                "filefront",
                                "fileback",
                            ] {
                                name(AssetKind::Texture, face);
                            }
                        }
                    }
                    _ => {}
                }
            }
            _ => {}
        }
        Ok(())
    }
}

/// A path's directory as MuJoCo 2.2.2 takes it (`mjuu_getfiledir`): everything up to and
/// including its last `/` or `\`, or nothing.
fn file_dir(path: &str) -> &str {
    path.rfind(['/', '\\']).map_or("", |i| &path[..=i])
}

/// A path's last component (`mjuu_strippath`).
fn last_component(path: &str) -> &str {
    path.rfind(['/', '\\']).map_or(path, |i| &path[i + 1..])
}

/// MuJoCo 2.2.2's test of an absolute path (`mjuu_isabspath`): a leading separator, or a
/// drive's `:/` or `:\` anywhere.
fn is_absolute(path: &str) -> bool {
    path.starts_with(['/', '\\']) || path.contains(":/") || path.contains(":\\")
}

/// An attribute value with XML's character references replaced, as the XML parser MuJoCo
/// uses replaces them; a reference it cannot read stays as written.
fn unescape(value: &str) -> Cow<'_, str> {
    if !value.contains('&') {
        return Cow::Borrowed(value);
    }
    let mut out = String::with_capacity(value.len());
    let mut rest = value;
    while let Some(amp) = rest.find('&') {
        out.push_str(&rest[..amp]);
        rest = &rest[amp..];
        let decoded = rest.find(';').and_then(|semi| {
            let entity = &rest[1..semi];
            let c = match entity {
                "amp" => Some('&'),
                "lt" => Some('<'),
                "gt" => Some('>'),
                "quot" => Some('"'),
                "apos" => Some('\''),
                _ => entity
                    .strip_prefix("#x")
                    .map(|hex| u32::from_str_radix(hex, 16))
                    .or_else(|| entity.strip_prefix('#').map(str::parse))
                    .and_then(Result::ok)
                    .and_then(char::from_u32),
            };
            c.map(|c| (c, semi + 1))
        });
        match decoded {
            Some((c, len)) => {
                out.push(c);
                rest = &rest[len..];
            }
            None => {
                out.push('&');
                rest = &rest[1..];
            }
        }
    }
    out.push_str(rest);
    Cow::Owned(out)
}
