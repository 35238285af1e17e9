//! A compiled MuJoCo model.

use super::{check_version, guard, MjError};
use mujoco_sys as sys;
use std::ffi::{c_char, CStr, CString};
use std::path::Path;
use std::ptr::NonNull;

/// Kinds of named objects that [`Model::id`] can look up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ObjectKind {
    Body,
    Joint,
    Geom,
    Site,
    Actuator,
}

impl ObjectKind {
    fn raw(self) -> sys::mjtObj {
        match self {
            ObjectKind::Body => sys::mjtObj::mjOBJ_BODY,
            ObjectKind::Joint => sys::mjtObj::mjOBJ_JOINT,
            ObjectKind::Geom => sys::mjtObj::mjOBJ_GEOM,
            ObjectKind::Site => sys::mjtObj::mjOBJ_SITE,
            ObjectKind::Actuator => sys::mjtObj::mjOBJ_ACTUATOR,
        }
    }

    fn name(self) -> &'static str {
        match self {
            ObjectKind::Body => "body",
            ObjectKind::Joint => "joint",
            ObjectKind::Geom => "geom",
            ObjectKind::Site => "site",
            ObjectKind::Actuator => "actuator",
        }
    }
}

/// A compiled model (`mjModel`), freed on drop. Read-only after loading, so it can be shared
/// between threads; each thread steps its own [`super::Data`].
pub struct Model {
    ptr: NonNull<sys::mjModel>,
    source_name: String,
}

// SAFETY: mjModel is plain heap memory owned by this handle; MuJoCo never mutates a model
// through `const mjModel*` (the only way the wrapper passes it after loading).
unsafe impl Send for Model {}
unsafe impl Sync for Model {}

const ERROR_BUF: usize = 1000;

/// The directory MuJoCo takes the text of [`Model::from_xml_with_files`] to be in: its
/// messages name a file the text reads `smirl-log/<name>`.
pub const IN_MEMORY_DIR: &str = "smirl-log";

/// The name MuJoCo reads the text of [`Model::from_xml_str`] under: it has no directory, so
/// relative names in the text resolve in the working directory.
pub const TEXT_ALONE_NAME: &str = "model.xml";

/// The name [`Model::from_xml_with_files`] gives its text among files of these `names`:
/// `smirl-log/model.xml`, or `smirl-log/model-1.xml`, ... when a file's key
/// ([`vfs_key`]) is `model.xml`, so that no file shadows the text.
pub fn in_memory_text_name<'a>(names: impl IntoIterator<Item = &'a str> + Clone) -> String {
    let name = (0..)
        .map(|n| match n {
            0 => TEXT_ALONE_NAME.to_string(),
            n => format!("model-{n}.xml"),
        })
        .find(|name| names.clone().into_iter().all(|file| vfs_key(file) != *name))
        .unwrap_or_default();
    format!("{IN_MEMORY_DIR}/{name}")
}

impl Model {
    /// Loads and compiles an MJCF file.
    pub fn from_xml_path(path: &Path) -> Result<Model, MjError> {
        let source_name = path.display().to_string();
        check_version()?;
        if !path.is_file() {
            return Err(MjError::Load {
                source_name,
                message: "no such file".into(),
            });
        }
        let c_path =
            CString::new(path.as_os_str().as_encoded_bytes()).map_err(|_| MjError::Load {
                source_name: source_name.clone(),
                message: "path contains a NUL byte".into(),
            })?;
        Self::load(&c_path, std::ptr::null(), source_name)
    }

    /// Compiles MJCF text. `source_name` names it in error messages (e.g. the file the text
    /// came from, or "embedded XML"). Relative `file=` references are not resolvable here.
    pub fn from_xml_str(xml: &str, source_name: &str) -> Result<Model, MjError> {
        let file_name = CString::new(TEXT_ALONE_NAME).expect("literal has no NUL");
        Self::load_text(xml, &file_name, source_name.into())
    }

    /// Compiles MJCF text with every file it reads given in memory, each as `(name, bytes)`
    /// under the name the text gives it: included MJCF files, and mesh, skin, height-field and
    /// texture files. Nothing is read from disk for a file given here, and nothing is written.
    ///
    /// MuJoCo 2.2 looks a file up in its virtual file system by the last component of the
    /// name, lower-cased, before it looks on disk, for includes and assets alike: each file
    /// goes in under that key, and two different files with one key cannot both go in (an
    /// error naming them; the same bytes twice are one file). The text goes in as
    /// `smirl-log/model.xml` (`model-1.xml`, ... when a file has that key), so MuJoCo takes
    /// `smirl-log/` for the text's directory: its messages name a file `smirl-log/<name>`, and
    /// a file the text names with a relative name and `files` lacks is looked for on disk
    /// under `smirl-log/` in the working directory, where none is expected (one with an
    /// absolute name at that name).
    pub fn from_xml_with_files(
        xml: &str,
        files: &[(&str, &[u8])],
        source_name: &str,
    ) -> Result<Model, MjError> {
        let refused = |message: String| MjError::Load {
            source_name: source_name.into(),
            message,
        };
        let mut entries: Vec<(String, &str, &[u8])> = Vec::with_capacity(files.len());
        for &(name, bytes) in files {
            let key = vfs_key(name);
            if key.is_empty() || key.len() >= sys::mjMAXVFSNAME as usize {
                return Err(refused(format!(
                    "file name '{name}' does not end in a name of 1 to {} bytes",
                    sys::mjMAXVFSNAME - 1
                )));
            }
            if bytes.is_empty() {
                return Err(refused(format!("file {name} is empty")));
            }
            match entries.iter().find(|(k, _, _)| *k == key) {
                Some((_, _, same)) if *same == bytes => {}
                Some((_, first, _)) => {
                    return Err(refused(format!(
                        "files {first} and {name} differ but share the name '{key}', and MuJoCo \
                         2.2 finds a file in memory by that name alone"
                    )))
                }
                None => entries.push((key, name, bytes)),
            }
        }
        if entries.len() + 1 >= sys::mjMAXVFS as usize {
            return Err(refused(format!(
                "{} files, more than MuJoCo's virtual file system holds",
                entries.len()
            )));
        }
        // The text is named with a directory: MuJoCo 2.2.2 reads the last four bytes of a
        // height field's or texture's name, its directory prepended, without checking that
        // there are four (a shorter one aborts the process); a directory makes every relative
        // name long enough. The virtual file system finds files by their last component, so
        // the directory changes no lookup.
        let main = in_memory_text_name(entries.iter().map(|(_, name, _)| *name));
        let c_name = |name: &str| {
            CString::new(name).map_err(|_| {
                refused(format!(
                    "file name '{}' holds a NUL byte",
                    name.escape_debug()
                ))
            })
        };
        check_version()?;
        let vfs = VfsBox::new();
        for (key, name, bytes) in &entries {
            vfs.add(&c_name(key)?, bytes, name, source_name)?;
        }
        let main = c_name(&main)?;
        vfs.add(&main, xml.as_bytes(), "the XML text", source_name)?;
        Self::load(&main, vfs.ptr, source_name.into())
    }

    /// Compiles `xml` put in a virtual file system under `file` (whose directory, when it has
    /// one, is where relative references resolve).
    fn load_text(xml: &str, file: &CStr, source_name: String) -> Result<Model, MjError> {
        check_version()?;
        let vfs = VfsBox::new();
        vfs.add(file, xml.as_bytes(), "the XML text", &source_name)?;
        Self::load(file, vfs.ptr, source_name)
    }

    fn load(file: &CStr, vfs: *const sys::mjVFS, source_name: String) -> Result<Model, MjError> {
        let mut error = [0 as c_char; ERROR_BUF];
        // SAFETY: file is NUL-terminated, vfs is null or valid, the error buffer has the size
        // passed.
        let raw = guard(|| unsafe {
            sys::mj_loadXML(file.as_ptr(), vfs, error.as_mut_ptr(), ERROR_BUF as i32)
        })?;
        match NonNull::new(raw) {
            Some(ptr) => Ok(Model { ptr, source_name }),
            None => {
                // SAFETY: MuJoCo writes a NUL-terminated message into the buffer on failure.
                let message = unsafe { CStr::from_ptr(error.as_ptr()) }
                    .to_string_lossy()
                    .trim()
                    .to_string();
                Err(MjError::Load {
                    source_name,
                    message: if message.is_empty() {
                        "unknown error".into()
                    } else {
                        message
                    },
                })
            }
        }
    }

    /// Where the model came from (path or the name given to [`Model::from_xml_str`]).
    pub fn source_name(&self) -> &str {
        &self.source_name
    }

    pub(crate) fn as_ptr(&self) -> *const sys::mjModel {
        self.ptr.as_ptr()
    }

    fn raw(&self) -> &sys::mjModel {
        // SAFETY: the pointer is valid for the lifetime of self.
        unsafe { self.ptr.as_ref() }
    }

    /// Id of a named object, or an error naming the object and the model.
    pub fn id(&self, kind: ObjectKind, name: &str) -> Result<usize, MjError> {
        let unknown = || MjError::UnknownName {
            kind: kind.name(),
            name: name.into(),
            model: self.source_name.clone(),
        };
        let c_name = CString::new(name).map_err(|_| unknown())?;
        // SAFETY: valid model and NUL-terminated name.
        let id = unsafe { sys::mj_name2id(self.as_ptr(), kind.raw() as i32, c_name.as_ptr()) };
        usize::try_from(id).map_err(|_| unknown())
    }

    pub fn nq(&self) -> usize {
        self.raw().nq as usize
    }
    pub fn nv(&self) -> usize {
        self.raw().nv as usize
    }
    pub fn nu(&self) -> usize {
        self.raw().nu as usize
    }
    pub fn nbody(&self) -> usize {
        self.raw().nbody as usize
    }
    pub fn njnt(&self) -> usize {
        self.raw().njnt as usize
    }
    pub fn ngeom(&self) -> usize {
        self.raw().ngeom as usize
    }
    pub fn nsite(&self) -> usize {
        self.raw().nsite as usize
    }

    /// Integration time step in seconds.
    pub fn timestep(&self) -> f64 {
        self.raw().opt.timestep
    }

    /// True when the integrator is 4th-order Runge–Kutta.
    pub fn uses_rk4(&self) -> bool {
        self.raw().opt.integrator == sys::mjtIntegrator::mjINT_RK4 as i32
    }

    fn slice<T>(&self, ptr: *const T, len: usize) -> &[T] {
        // SAFETY: every model array the wrapper exposes has the length MuJoCo documents for
        // it, and lives as long as the model.
        unsafe { std::slice::from_raw_parts(ptr, len) }
    }

    /// Index of a body in `mocap_pos` when it is a mocap body (a body of the world whose
    /// position each [`super::Data`] sets, with no degrees of freedom).
    pub fn body_mocap_id(&self, body: usize) -> Option<usize> {
        usize::try_from(self.slice(self.raw().body_mocapid, self.nbody())[body]).ok()
    }

    /// Number of mocap bodies.
    pub fn nmocap(&self) -> usize {
        self.raw().nmocap as usize
    }

    /// Position of a body in its parent's frame, as the model gives it.
    pub fn body_pos(&self, body: usize) -> [f64; 3] {
        let s = &self.slice(self.raw().body_pos, 3 * self.nbody())[3 * body..3 * body + 3];
        [s[0], s[1], s[2]]
    }

    /// Index of a joint's first value in `qpos`.
    pub fn joint_qpos_addr(&self, joint: usize) -> usize {
        self.slice(self.raw().jnt_qposadr, self.njnt())[joint] as usize
    }

    /// Index of a joint's first value in `qvel`.
    pub fn joint_dof_addr(&self, joint: usize) -> usize {
        self.slice(self.raw().jnt_dofadr, self.njnt())[joint] as usize
    }

    /// Body a joint moves (the body it is declared in).
    pub fn joint_body(&self, joint: usize) -> usize {
        self.slice(self.raw().jnt_bodyid, self.njnt())[joint] as usize
    }

    /// `Some((lo, hi))` when the joint is limited.
    pub fn joint_range(&self, joint: usize) -> Option<(f64, f64)> {
        let limited = self.slice(self.raw().jnt_limited, self.njnt())[joint] != 0;
        let range = self.slice(self.raw().jnt_range, 2 * self.njnt());
        limited.then(|| (range[2 * joint], range[2 * joint + 1]))
    }

    pub fn dof_armature(&self, dof: usize) -> f64 {
        self.slice(self.raw().dof_armature, self.nv())[dof]
    }

    pub fn dof_damping(&self, dof: usize) -> f64 {
        self.slice(self.raw().dof_damping, self.nv())[dof]
    }

    /// `Some((lo, hi))` when the actuator's control is limited.
    pub fn actuator_ctrl_range(&self, actuator: usize) -> Option<(f64, f64)> {
        let limited = self.slice(self.raw().actuator_ctrllimited, self.nu())[actuator] != 0;
        let range = self.slice(self.raw().actuator_ctrlrange, 2 * self.nu());
        limited.then(|| (range[2 * actuator], range[2 * actuator + 1]))
    }

    /// First gear coefficient of an actuator (the torque scale of a motor on a hinge).
    pub fn actuator_gear(&self, actuator: usize) -> f64 {
        self.slice(self.raw().actuator_gear, 6 * self.nu())[6 * actuator]
    }

    /// Joint driven by an actuator (for joint transmissions).
    pub fn actuator_joint(&self, actuator: usize) -> usize {
        self.slice(self.raw().actuator_trnid, 2 * self.nu())[2 * actuator] as usize
    }

    /// Collision bit masks `(contype, conaffinity)` of a geom.
    pub fn geom_collision_masks(&self, geom: usize) -> (i32, i32) {
        let n = self.ngeom();
        (
            self.slice(self.raw().geom_contype, n)[geom],
            self.slice(self.raw().geom_conaffinity, n)[geom],
        )
    }

    /// Body a geom is attached to.
    pub fn geom_body(&self, geom: usize) -> usize {
        self.slice(self.raw().geom_bodyid, self.ngeom())[geom] as usize
    }

    /// First size parameter of a geom (the radius of a sphere or capsule).
    pub fn geom_radius(&self, geom: usize) -> f64 {
        self.slice(self.raw().geom_size, 3 * self.ngeom())[3 * geom]
    }

    /// World-frame end points of the axis of a capsule attached to the world body (e.g. an
    /// arena wall given by `fromto`): the geom's position ± its half-length (second size
    /// parameter) along the z-axis of its orientation. `None` for any other geom (its model
    /// position would be relative to a moving body).
    pub fn world_capsule_segment(&self, geom: usize) -> Option<([f64; 3], [f64; 3])> {
        let n = self.ngeom();
        let kind = self.slice(self.raw().geom_type, n)[geom];
        let body = self.slice(self.raw().geom_bodyid, n)[geom];
        if kind != sys::mjtGeom::mjGEOM_CAPSULE as i32 || body != 0 {
            return None;
        }
        let p = &self.slice(self.raw().geom_pos, 3 * n)[3 * geom..3 * geom + 3];
        let q = &self.slice(self.raw().geom_quat, 4 * n)[4 * geom..4 * geom + 4];
        let half = self.slice(self.raw().geom_size, 3 * n)[3 * geom + 1];
        let (w, x, y, z) = (q[0], q[1], q[2], q[3]);
        // Third column of the rotation matrix of the unit quaternion (w, x, y, z).
        let axis = [
            2.0 * (x * z + w * y),
            2.0 * (y * z - w * x),
            1.0 - 2.0 * (x * x + y * y),
        ];
        let end = |sign: f64| std::array::from_fn(|k| p[k] + sign * half * axis[k]);
        Some((end(-1.0), end(1.0)))
    }

    /// Colour of a geom as the XML gives it (RGBA, each 0–1).
    pub fn geom_rgba(&self, geom: usize) -> [f32; 4] {
        let s = self.slice(self.raw().geom_rgba, 4 * self.ngeom());
        [
            s[4 * geom],
            s[4 * geom + 1],
            s[4 * geom + 2],
            s[4 * geom + 3],
        ]
    }
}

impl Drop for Model {
    fn drop(&mut self) {
        // SAFETY: the model was allocated by mj_loadXML and is freed once.
        unsafe { sys::mj_deleteModel(self.ptr.as_ptr()) };
    }
}

impl std::fmt::Debug for Model {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Model")
            .field("source", &self.source_name)
            .field("nq", &self.nq())
            .field("nv", &self.nv())
            .field("nu", &self.nu())
            .finish()
    }
}

/// A heap-allocated, initialised `mjVFS`, deleted on drop.
struct VfsBox {
    ptr: *mut sys::mjVFS,
}

impl VfsBox {
    /// An empty virtual file system. mjVFS is about 2 MB in 2.2: it lives on the heap, never
    /// on the stack.
    fn new() -> VfsBox {
        let layout = std::alloc::Layout::new::<sys::mjVFS>();
        // SAFETY: layout is non-zero-sized; mj_defaultVFS initialises every field.
        unsafe {
            let ptr = std::alloc::alloc_zeroed(layout) as *mut sys::mjVFS;
            if ptr.is_null() {
                std::alloc::handle_alloc_error(layout);
            }
            sys::mj_defaultVFS(ptr);
            VfsBox { ptr }
        }
    }

    /// Puts `bytes` (not empty) in under `file`; `what` names them in an error about a model
    /// from `source_name`.
    fn add(&self, file: &CStr, bytes: &[u8], what: &str, source_name: &str) -> Result<(), MjError> {
        let refused = |message: String| MjError::Load {
            source_name: source_name.into(),
            message,
        };
        let size = i32::try_from(bytes.len())
            .map_err(|_| refused(format!("{what} is larger than 2 GiB")))?;
        let vfs = self.ptr;
        // SAFETY: vfs points to an initialised mjVFS; the file slot is created with exactly
        // `size` bytes and filled with as many.
        let status = guard(|| unsafe {
            let code = sys::mj_makeEmptyFileVFS(vfs, file.as_ptr(), size);
            if code != 0 {
                return code;
            }
            let index = sys::mj_findFileVFS(vfs, file.as_ptr());
            if index < 0 {
                return -1;
            }
            let slot = (*vfs).filedata[index as usize] as *mut u8;
            std::ptr::copy_nonoverlapping(bytes.as_ptr(), slot, bytes.len());
            0
        })?;
        if status != 0 {
            return Err(refused(format!(
                "MuJoCo's virtual file system refused {what} (code {status})"
            )));
        }
        Ok(())
    }
}

/// The key MuJoCo 2.2 files a name under in its virtual file system (`vfs_strippath`), and
/// looks a name up by: the name's last component, after its last `/` or `\`, lower-cased.
pub fn vfs_key(name: &str) -> String {
    let last = name.rfind(['/', '\\']).map_or(name, |i| &name[i + 1..]);
    last.to_ascii_lowercase()
}

impl Drop for VfsBox {
    fn drop(&mut self) {
        // SAFETY: ptr came from alloc_zeroed with this layout and was initialised; the VFS
        // frees its file buffers before the block itself is freed.
        unsafe {
            sys::mj_deleteVFS(self.ptr);
            std::alloc::dealloc(self.ptr as *mut u8, std::alloc::Layout::new::<sys::mjVFS>());
        }
    }
}
