//! The one shader path of the harness: the SPIR-V of its own shaders (compiled by build.rs from
//! `harness/shaders/`, or at first use when the build had no glslangValidator), every GLSL it compiles
//! at run time (resource-state stages, the build checks' shaders) through [`compile_glsl`] — in this
//! process, with the shaderc library linked into the binary, memoised by content — and the one place
//! SPIR-V becomes a shader module ([`module`]).

use crate::error::{vkfail, HarnessError};
use crate::vk::VkDevice;
use ash::vk;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::sync::Mutex;

include!(concat!(env!("OUT_DIR"), "/shaders.rs"));

/// Shader kinds: one SPIR-V module each per API, made per group by constant 0 (the group index), written
/// into the module (`with_spec_values`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
pub enum ShaderKind {
    /// Raygen that traces into the scene at binding 0.
    RaygenTrace,
    /// Raygen without a scene binding (the case traces no rays).
    RaygenPlain,
    Miss,
    /// Closest-hit that traces its ray again while the launch's extra recursion allows (scene at binding 0).
    ClosestHitTrace,
    /// Closest-hit without a scene binding (pipelines of launches that trace no ray).
    ClosestHitPlain,
    AnyHit,
    Intersection,
    Callable,
}

/// What a shader's `main` does. A case that is only recorded under the layer (invalid: never
/// submitted) runs no shader, and the layer reads a module's interface (the variables its entry point
/// uses, its capabilities), never its code's effects; lavapipe's pipeline creation time grows with the
/// code. So such a case gets the interface-only body (`-DINTERFACE_ONLY`): one use of each variable
/// the full body uses, nothing computed, and no trace: the source traces the scene once, and
/// `ShaderBody::module_words` removes the instruction, keeping the scene's load. A test compares
/// the two bodies' interfaces for every kind and API.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
pub enum ShaderBody {
    /// The body that writes the records: every case that runs.
    Full,
    /// The least code with the full body's interface: cases that are never submitted.
    InterfaceOnly,
}

impl ShaderBody {
    /// The body of a case run as valid (submitted) or only recorded.
    pub fn for_run(run_valid: bool) -> ShaderBody {
        if run_valid {
            ShaderBody::Full
        } else {
            ShaderBody::InterfaceOnly
        }
    }

    /// The preprocessor names that select the body.
    pub(crate) fn defines(self) -> &'static [&'static str] {
        match self {
            ShaderBody::Full => &[],
            ShaderBody::InterfaceOnly => &["INTERFACE_ONLY"],
        }
    }

    /// The module of the body from what glslang made of its source with [`ShaderBody::defines`]:
    /// as it is for the full body, [`without_traces`] for the interface-only one.
    pub(crate) fn module_words(self, words: Vec<u32>) -> Vec<u32> {
        match self {
            ShaderBody::Full => words,
            ShaderBody::InterfaceOnly => without_traces(&words),
        }
    }
}

/// Which ray tracing extension a module is written for: GL_EXT_ray_tracing (SPV_KHR_ray_tracing) for KHR
/// pipelines, GL_NV_ray_tracing (SPV_NV_ray_tracing, `-DNV`) for `vkCreateRayTracingPipelinesNV`.
pub use model::world::PipelineApi as ShaderApi;

impl ShaderKind {
    /// The name of the kind's SPIR-V (`raygen_trace`).
    pub fn output_name(self) -> &'static str {
        match self {
            ShaderKind::RaygenTrace => "raygen_trace",
            ShaderKind::RaygenPlain => "raygen_plain",
            ShaderKind::Miss => "miss",
            ShaderKind::ClosestHitTrace => "closest_hit_trace",
            ShaderKind::ClosestHitPlain => "closest_hit_plain",
            ShaderKind::AnyHit => "any_hit",
            ShaderKind::Intersection => "intersection",
            ShaderKind::Callable => "callable",
        }
    }

    /// The output name of the variant for `api` and `body` (`<name>`, `<name>_nv`, then
    /// `_interface` for the interface-only body), as build.rs names it.
    pub fn variant_name(self, api: ShaderApi, body: ShaderBody) -> String {
        let nv = match api {
            ShaderApi::Khr => "",
            ShaderApi::Nv => "_nv",
        };
        let interface = match body {
            ShaderBody::Full => "",
            ShaderBody::InterfaceOnly => "_interface",
        };
        format!("{}{nv}{interface}", self.output_name())
    }

    /// The GLSL file, its text and the defines of the kind's variant.
    fn source(self) -> (&'static str, &'static str, &'static [&'static str]) {
        match self {
            ShaderKind::RaygenTrace => (
                "raygen.rgen",
                include_str!("../shaders/raygen.rgen"),
                &["-DTRACE"],
            ),
            ShaderKind::RaygenPlain => ("raygen.rgen", include_str!("../shaders/raygen.rgen"), &[]),
            ShaderKind::Miss => ("miss.rmiss", include_str!("../shaders/miss.rmiss"), &[]),
            ShaderKind::ClosestHitTrace => (
                "closest_hit.rchit",
                include_str!("../shaders/closest_hit.rchit"),
                &["-DTRACE"],
            ),
            ShaderKind::ClosestHitPlain => (
                "closest_hit.rchit",
                include_str!("../shaders/closest_hit.rchit"),
                &[],
            ),
            ShaderKind::AnyHit => (
                "any_hit.rahit",
                include_str!("../shaders/any_hit.rahit"),
                &[],
            ),
            ShaderKind::Intersection => (
                "intersection.rint",
                include_str!("../shaders/intersection.rint"),
                &[],
            ),
            ShaderKind::Callable => (
                "callable.rcall",
                include_str!("../shaders/callable.rcall"),
                &[],
            ),
        }
    }
}

/// The record layout the shaders write must be the model's (`RECORD_WORDS`, the outcome codes and the
/// word positions in `shaders/*.r*`).
const _: () = {
    use model::tracer::record::RayRecord as R;
    assert!(R::WORDS == 28 && R::SEEN_SLOTS == 4);
    assert!(R::MISS == 1 && R::HIT == 2 && R::NO_SHADER == 3 && R::NO_GROUP == 0xFFFF_FFFF);
    assert!(R::ANY_HIT_COUNT == 10 && R::INTERSECTION_COUNT == 11 && R::SEEN == 12);
    assert!(R::T == 7 && R::BARYCENTRICS == 8 && R::GEOMETRY_INDEX == 4);
};

/// The SPIR-V words of a shader kind for a pipeline API and body.
pub(crate) fn spirv(
    kind: ShaderKind,
    api: ShaderApi,
    body: ShaderBody,
) -> Result<Vec<u32>, HarnessError> {
    let name = kind.variant_name(api, body);
    let compiled = match PRECOMPILED
        .iter()
        .find(|(n, _)| *n == name)
        .and_then(|(_, b)| *b)
    {
        Some(b) => words(&name, b),
        None => compile_source(kind, api, body),
    };
    compiled.map(|w| body.module_words(w))
}

/// What glslang makes of a kind's source for an API and body (before [`ShaderBody::module_words`]),
/// compiled in this process: for a build whose precompiled modules are missing.
fn compile_source(
    kind: ShaderKind,
    api: ShaderApi,
    body: ShaderBody,
) -> Result<Vec<u32>, HarnessError> {
    let (file, text, args) = kind.source();
    let ext = file.rsplit('.').next().unwrap_or(file);
    let mut defines: Vec<&str> = args.iter().map(|a| a.trim_start_matches("-D")).collect();
    if api == ShaderApi::Nv {
        defines.push("NV");
    }
    defines.extend(body.defines());
    compile_glsl(file, ext, text, &defines)
}

/// SPIR-V bytes as words, checked for the size of a module.
fn words(name: &str, bytes: &[u8]) -> Result<Vec<u32>, HarnessError> {
    if bytes.len() % 4 != 0 || bytes.len() < 20 {
        return Err(HarnessError::Shader(format!(
            "{name}: not SPIR-V ({} bytes)",
            bytes.len()
        )));
    }
    Ok(bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

/// Compiles GLSL to SPIR-V words in this process, with the shaderc library linked into the binary
/// (Vulkan 1.2 target, so SPIR-V 1.5, as `glslangValidator --target-env vulkan1.2 -V` gives): `ext` is
/// the stage's file extension (`rgen`, `rchit`, `comp`, …), `defines` the preprocessor names (`TRACE`,
/// `NV`), `what` names the shader in errors. No process is spawned and no tool on PATH is needed.
/// Results are memoised in this process by content, and on disk ([`disk`]) across processes.
pub(crate) fn compile_glsl(
    what: &str,
    ext: &str,
    text: &str,
    defines: &[&str],
) -> Result<Vec<u32>, HarnessError> {
    use std::hash::{Hash, Hasher};
    static MEMO: Mutex<Option<HashMap<u64, Vec<u32>>>> = Mutex::new(None);
    let mut h = std::collections::hash_map::DefaultHasher::new();
    (text, ext, defines).hash(&mut h);
    let key = h.finish();
    if let Some(w) = MEMO
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .get_or_insert_with(HashMap::new)
        .get(&key)
    {
        return Ok(w.clone());
    }
    let on_disk = disk::entry(ext, text, defines);
    if let Some(w) = on_disk.as_deref().and_then(disk::read) {
        MEMO.lock()
            .unwrap_or_else(|e| e.into_inner())
            .get_or_insert_with(HashMap::new)
            .insert(key, w.clone());
        return Ok(w);
    }
    let stage = glsl::Stage::of_extension(ext).ok_or_else(|| {
        HarnessError::Shader(format!(
            "{what}: no shader stage has the file extension `.{ext}`"
        ))
    })?;
    let bytes = {
        let _phase = crate::timing::span(crate::timing::Phase::Shaders);
        glsl::compile(&format!("{what}.{ext}"), stage, text, defines)
    }
    .map_err(|message| HarnessError::Shader(format!("{what}: {message}\n{text}")))?;
    let w = words(what, &bytes)?;
    if let Some(path) = &on_disk {
        disk::write(path, &bytes);
    }
    MEMO.lock()
        .unwrap_or_else(|e| e.into_inner())
        .get_or_insert_with(HashMap::new)
        .insert(key, w.clone());
    Ok(w)
}

/// The SPIR-V the linked compiler made, kept across processes: each worker of a run, and every later
/// run on the machine, finds a shader an earlier one compiled instead of compiling it again (the first
/// compilation of each stage kind also pays glslang's start-up). An entry is a file named by the
/// 128-bit fingerprint of the stage's extension, its defines, its source and the linked compiler's
/// identity (its archives' sizes and times, from build.rs), in a folder under the temporary
/// directory; it is written whole (a temporary file, then a rename) and read back only if it is a
/// SPIR-V module (magic number, whole words). `RTCONF_SPIRV_CACHE=off` turns it off.
pub(crate) mod disk {
    use std::path::{Path, PathBuf};

    /// SPIR-V's magic number, the first word of every module.
    const MAGIC: u32 = 0x0723_0203;

    /// The entry's path for a stage, or None when the cache is off.
    pub(super) fn entry(ext: &str, text: &str, defines: &[&str]) -> Option<PathBuf> {
        if std::env::var_os("RTCONF_SPIRV_CACHE").is_some_and(|v| v == "off") {
            return None;
        }
        let identity = env!("RTCONF_SHADERC_IDENTITY");
        let key = model::fingerprint::of(&(identity, ext, defines, text))?;
        Some(
            std::env::temp_dir()
                .join("rtconf-spirv")
                .join(format!("{key:032x}.spv")),
        )
    }

    /// The entry's words, if it holds a module.
    pub(super) fn read(path: &Path) -> Option<Vec<u32>> {
        // A module of these shaders is some kilobytes.
        let bytes =
            vk_registry::input::read_at_most(path, 16 * vk_registry::input::MIB, "a shader module")
                .ok()?;
        if bytes.len() < 20 || bytes.len() % 4 != 0 {
            return None;
        }
        let words: Vec<u32> = bytes
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        (words[0] == MAGIC).then_some(words)
    }

    /// Writes an entry whole; a cache that cannot be written is only slower.
    pub(crate) fn write(path: &Path, bytes: &[u8]) {
        let Some(dir) = path.parent() else { return };
        if std::fs::create_dir_all(dir).is_err() {
            return;
        }
        // Named for this process and this write, so two threads writing one entry never share it.
        static WRITES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let staged = dir.join(format!(
            ".{}.{}.{}.tmp",
            path.file_name().and_then(|n| n.to_str()).unwrap_or("entry"),
            std::process::id(),
            WRITES.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
        ));
        if std::fs::write(&staged, bytes).is_ok() && std::fs::rename(&staged, path).is_ok() {
            return;
        }
        let _ = std::fs::remove_file(&staged);
    }
}

/// The shaderc library's C interface, as much of it as [`compile_glsl`] uses (`shaderc/shaderc.h` of
/// libshaderc-dev; build.rs links it and the glslang and SPIRV-Tools archives it needs statically).
mod glsl {
    use std::ffi::{c_char, c_int, c_void, CStr, CString};
    use std::sync::OnceLock;

    /// `shaderc_shader_kind` values of the stages the harness compiles.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    #[repr(i32)]
    pub(super) enum Stage {
        Compute = 2,
        Raygen = 14,
        AnyHit = 15,
        ClosestHit = 16,
        Miss = 17,
        Intersection = 18,
        Callable = 19,
    }

    impl Stage {
        /// The stage a file extension names, as glslangValidator infers it.
        pub(super) fn of_extension(ext: &str) -> Option<Stage> {
            Some(match ext {
                "comp" => Stage::Compute,
                "rgen" => Stage::Raygen,
                "rahit" => Stage::AnyHit,
                "rchit" => Stage::ClosestHit,
                "rmiss" => Stage::Miss,
                "rint" => Stage::Intersection,
                "rcall" => Stage::Callable,
                _ => return None,
            })
        }
    }

    const TARGET_ENV_VULKAN: c_int = 0;
    /// `shaderc_env_version_vulkan_1_2`: VK_MAKE_VERSION(1, 2, 0).
    const ENV_VERSION_VULKAN_1_2: u32 = (1 << 22) | (2 << 12);
    const STATUS_SUCCESS: c_int = 0;

    // Linked by build.rs: libshaderc_combined.a, then the archives it needs, in order.
    extern "C" {
        fn shaderc_compiler_initialize() -> *mut c_void;
        fn shaderc_compile_options_initialize() -> *mut c_void;
        fn shaderc_compile_options_release(options: *mut c_void);
        fn shaderc_compile_options_add_macro_definition(
            options: *mut c_void,
            name: *const c_char,
            name_length: usize,
            value: *const c_char,
            value_length: usize,
        );
        fn shaderc_compile_options_set_target_env(
            options: *mut c_void,
            target: c_int,
            version: u32,
        );
        fn shaderc_compile_into_spv(
            compiler: *const c_void,
            source_text: *const c_char,
            source_text_size: usize,
            shader_kind: c_int,
            input_file_name: *const c_char,
            entry_point_name: *const c_char,
            additional_options: *const c_void,
        ) -> *mut c_void;
        fn shaderc_result_release(result: *mut c_void);
        fn shaderc_result_get_length(result: *const c_void) -> usize;
        fn shaderc_result_get_compilation_status(result: *const c_void) -> c_int;
        fn shaderc_result_get_bytes(result: *const c_void) -> *const c_char;
        fn shaderc_result_get_error_message(result: *const c_void) -> *const c_char;
    }

    /// The process's one compiler object, never released.
    struct Compiler(*mut c_void);
    // SAFETY: shaderc_compile_into_spv takes the compiler as const and "may be safely called from
    // multiple threads without explicit synchronization" (shaderc.h); nothing else uses the pointer.
    unsafe impl Send for Compiler {}
    // SAFETY: as for Send: only const uses are shared.
    unsafe impl Sync for Compiler {}

    fn compiler() -> Result<*const c_void, String> {
        static COMPILER: OnceLock<Compiler> = OnceLock::new();
        // SAFETY: no arguments; the result is checked for null.
        let c = COMPILER.get_or_init(|| Compiler(unsafe { shaderc_compiler_initialize() }));
        if c.0.is_null() {
            Err("the shaderc compiler could not be initialised".into())
        } else {
            Ok(c.0)
        }
    }

    /// Releases the options and the result when the compilation ends, whichever way.
    struct Owned {
        options: *mut c_void,
        result: *mut c_void,
    }
    impl Drop for Owned {
        fn drop(&mut self) {
            // SAFETY: each pointer is null or came from its initialiser and is released once, here;
            // both release functions accept null.
            unsafe {
                if !self.result.is_null() {
                    shaderc_result_release(self.result);
                }
                shaderc_compile_options_release(self.options);
            }
        }
    }

    /// Compiles `text` as `stage` (entry point `main`) with `defines` (each defined empty, as
    /// glslangValidator's `-DNAME`): the module's bytes, or the compiler's message.
    pub(super) fn compile(
        name: &str,
        stage: Stage,
        text: &str,
        defines: &[&str],
    ) -> Result<Vec<u8>, String> {
        let compiler = compiler()?;
        let file = CString::new(name).map_err(|_| format!("the name {name:?} holds a NUL byte"))?;
        // SAFETY: no arguments; checked for null before use.
        let mut owned = Owned {
            options: unsafe { shaderc_compile_options_initialize() },
            result: std::ptr::null_mut(),
        };
        if owned.options.is_null() {
            return Err("the shaderc options could not be initialised".into());
        }
        // SAFETY: `owned.options` is live; each name is read for its length only (no NUL needed), and
        // a null value with length 0 defines the macro empty.
        unsafe {
            shaderc_compile_options_set_target_env(
                owned.options,
                TARGET_ENV_VULKAN,
                ENV_VERSION_VULKAN_1_2,
            );
            for d in defines {
                shaderc_compile_options_add_macro_definition(
                    owned.options,
                    d.as_ptr().cast(),
                    d.len(),
                    std::ptr::null(),
                    0,
                );
            }
        }
        // SAFETY: the compiler and options are live; the source is read for `text.len()` bytes; the
        // file and entry point names are NUL-terminated.
        owned.result = unsafe {
            shaderc_compile_into_spv(
                compiler,
                text.as_ptr().cast(),
                text.len(),
                stage as c_int,
                file.as_ptr(),
                c"main".as_ptr(),
                owned.options,
            )
        };
        if owned.result.is_null() {
            return Err("shaderc returned no result".into());
        }
        let r = owned.result;
        // SAFETY: `r` is a live result; the message is NUL-terminated and the bytes are
        // `shaderc_result_get_length` long, both owned by `r`, copied before it is released.
        unsafe {
            if shaderc_result_get_compilation_status(r) != STATUS_SUCCESS {
                let m = shaderc_result_get_error_message(r);
                let message = if m.is_null() {
                    String::from("the compiler gave no message")
                } else {
                    CStr::from_ptr(m).to_string_lossy().into_owned()
                };
                return Err(message);
            }
            let (bytes, len) = (shaderc_result_get_bytes(r), shaderc_result_get_length(r));
            if bytes.is_null() {
                return Err("the compiler gave no module".into());
            }
            Ok(std::slice::from_raw_parts(bytes.cast::<u8>(), len).to_vec())
        }
    }
}

/// The interface-only module of compiled interface-only SPIR-V: every trace instruction removed
/// (OpTraceRayKHR, OpTraceNV, OpTraceRayMotionNV; none has a result). The loads of the scene that fed
/// them stay, and so does the scene's static use — a load names the variable —; each payload is
/// stored by the interface-only body, so its use stays too. Lavapipe inlines the whole traversal,
/// with every hit group's shaders, at each trace; without one a pipeline is its stages alone. A
/// truncated instruction ends the module there.
pub(crate) fn without_traces(words: &[u32]) -> Vec<u32> {
    const OP_TRACE_NV: u32 = 5337;
    const OP_TRACE_RAY_MOTION_NV: u32 = 5339;
    const OP_TRACE_RAY_KHR: u32 = 4445;
    let mut out = Vec::with_capacity(words.len());
    out.extend_from_slice(&words[..words.len().min(5)]);
    let mut i = 5;
    while i < words.len() {
        let count = (words[i] >> 16) as usize;
        if count == 0 || i + count > words.len() {
            break;
        }
        let op = words[i] & 0xFFFF;
        if !matches!(op, OP_TRACE_RAY_KHR | OP_TRACE_NV | OP_TRACE_RAY_MOTION_NV) {
            out.extend_from_slice(&words[i..i + count]);
        }
        i += count;
    }
    out
}

/// The instructions of a SPIR-V module after its five-word header, each with the position of its first
/// word: an instruction whose word count reads 0 is taken as one word, and a truncated one ends the
/// module.
pub(crate) fn instructions(words: &[u32]) -> impl Iterator<Item = (usize, &[u32])> + '_ {
    let mut i = 5;
    std::iter::from_fn(move || {
        let count = ((*words.get(i)? >> 16) as usize).max(1);
        let inst = words.get(i..i + count)?;
        let at = i;
        i += count;
        Some((at, inst))
    })
}

/// The module with each 32-bit specialisation constant whose SpecId is `i < values.len()` made an
/// ordinary constant of value `values[i]` (its OpSpecConstant an OpConstant of the same words, its
/// SpecId decoration removed): used without specialisation info, it computes what the original module
/// specialised with those values computes. Constants with other IDs, and every other instruction, are
/// kept.
///
/// Why ordinary constants and not new default values: a validation layer that finds specialisation
/// constants in a module specialises and validates the module again (spirv-opt, then spirv-val) for
/// every pipeline stage made of it, specialisation info or not; a module without them is validated
/// once, when it is made (layer 1.3.239 on lavapipe: more than half of a ray tracing pipeline's
/// creation went there).
pub(crate) fn with_spec_values(words: &[u32], values: &[u32]) -> Vec<u32> {
    constants_for_spec(words, |id| values.get(id as usize).copied().map(Some))
}

/// The first SpecId of the specialisation constants the harness's GLSL declares only to be made
/// ordinary constants of their default values ([`with_fixed_spec_defaults`]); its own shaders' IDs
/// (group index, any-hit rule) lie below it.
pub(crate) const FIXED_SPEC_ID_BASE: u32 = 100;

/// The module with each 32-bit specialisation constant whose SpecId is at least
/// [`FIXED_SPEC_ID_BASE`] made an ordinary constant of its default value: how a module gets a constant
/// that GLSL refuses to write as one (an array index past the array's end, which the compiler
/// rejects as a constant but accepts as a specialisation constant's default).
pub(crate) fn with_fixed_spec_defaults(words: &[u32]) -> Vec<u32> {
    constants_for_spec(words, |id| (id >= FIXED_SPEC_ID_BASE).then_some(None))
}

/// The module with the 32-bit specialisation constants `value_of` picks made ordinary constants:
/// `value_of(spec_id)` is None to keep the constant, `Some(None)` to keep its default value and
/// `Some(Some(v))` to give it value `v` (its OpSpecConstant an OpConstant of the same words, its
/// SpecId decoration removed). Every other instruction is kept.
fn constants_for_spec(words: &[u32], value_of: impl Fn(u32) -> Option<Option<u32>>) -> Vec<u32> {
    const OP_CONSTANT: u32 = 43;
    const OP_SPEC_CONSTANT: u32 = 50;
    const OP_DECORATE: u32 = 71;
    const SPEC_ID: u32 = 1;
    // Result id → the value it gets (None: its default).
    let mut value_for: BTreeMap<u32, Option<u32>> = BTreeMap::new();
    for (_, inst) in instructions(words) {
        if inst[0] & 0xFFFF == OP_DECORATE && inst.len() == 4 && inst[2] == SPEC_ID {
            if let Some(v) = value_of(inst[3]) {
                value_for.insert(inst[1], v);
            }
        }
    }
    let mut out = Vec::with_capacity(words.len());
    out.extend_from_slice(&words[..words.len().min(5)]);
    // Words after the last whole instruction (a truncated one) are kept as they are.
    let mut end = out.len();
    for (at, inst) in instructions(words) {
        end = at + inst.len();
        let op = inst[0] & 0xFFFF;
        if op == OP_DECORATE
            && inst.len() == 4
            && inst[2] == SPEC_ID
            && value_for.contains_key(&inst[1])
        {
            continue;
        }
        // OpSpecConstant %type %id value: one word for a 32-bit constant, laid out as OpConstant.
        match value_for.get(&inst.get(2).copied().unwrap_or(0)) {
            Some(&v) if op == OP_SPEC_CONSTANT && inst.len() == 4 => {
                out.extend_from_slice(&[
                    (inst[0] & !0xFFFF) | OP_CONSTANT,
                    inst[1],
                    inst[2],
                    v.unwrap_or(inst[3]),
                ]);
            }
            _ => out.extend_from_slice(inst),
        }
    }
    out.extend_from_slice(&words[end..]);
    out
}

/// A shader module of SPIR-V words on a device; the caller destroys it.
pub(crate) fn module(dev: &VkDevice, code: &[u32]) -> Result<vk::ShaderModule, HarnessError> {
    let mut remembered = dev.validated.as_ref().map(|v| {
        vk::ShaderModuleValidationCacheCreateInfoEXT::default().validation_cache(v.cache())
    });
    let mut info = vk::ShaderModuleCreateInfo::default().code(code);
    if let Some(r) = remembered.as_mut() {
        info = info.push_next(r);
    }
    // SAFETY: `code` is SPIR-V from glslang (checked for a module's size); `info` outlives the call.
    unsafe { dev.device.create_shader_module(&info, None) }.map_err(vkfail("vkCreateShaderModule"))
}

/// What a validation layer reads of a module without running it: the execution model, the
/// capabilities and extensions, the specialisation constant IDs, and each module-scope variable the
/// entry point statically uses, as its storage class with its set, binding, location and built-in
/// decorations. Static use is found as a layer finds it: the instructions of the functions the entry
/// point reaches through calls that name the variable (loads, stores, access chains, atomics, array
/// lengths, texel pointers, copies, traces and callable executions — the NV ones by their payload's
/// location). OpEntryPoint's list is not used: glslang lists every module-scope variable there.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ModuleInterface {
    pub model: u32,
    pub capabilities: BTreeSet<u32>,
    pub extensions: BTreeSet<String>,
    pub spec_ids: BTreeSet<u32>,
    /// (storage class, set, binding, location, built-in), u32::MAX where not decorated.
    pub variables: BTreeSet<[u32; 5]>,
}

/// The [`ModuleInterface`] of a SPIR-V module's first entry point, read from its words alone (a
/// truncated instruction ends the reading).
pub fn module_interface(words: &[u32]) -> ModuleInterface {
    const NONE: u32 = u32::MAX;
    // SPIR-V opcodes and storage classes read here.
    const OP_EXTENSION: u32 = 10;
    const OP_ENTRY_POINT: u32 = 15;
    const OP_CAPABILITY: u32 = 17;
    const OP_FUNCTION: u32 = 54;
    const OP_FUNCTION_END: u32 = 56;
    const OP_FUNCTION_CALL: u32 = 57;
    const OP_VARIABLE: u32 = 59;
    const OP_DECORATE: u32 = 71;
    const OP_TRACE_NV: u32 = 5337;
    const OP_EXECUTE_CALLABLE_NV: u32 = 5344;
    const RAY_PAYLOAD: u32 = 5338;
    const CALLABLE_DATA: u32 = 5328;
    let text = |ws: &[u32]| -> String {
        let b: Vec<u8> = ws.iter().flat_map(|w| w.to_le_bytes()).collect();
        String::from_utf8_lossy(b.split(|&c| c == 0).next().unwrap_or(&[])).into_owned()
    };
    let mut out = ModuleInterface {
        model: NONE,
        capabilities: BTreeSet::new(),
        extensions: BTreeSet::new(),
        spec_ids: BTreeSet::new(),
        variables: BTreeSet::new(),
    };
    let mut entry = NONE;
    let mut decorations: BTreeMap<u32, [u32; 4]> = BTreeMap::new();
    // Module-scope variables: id → storage class.
    let mut globals: BTreeMap<u32, u32> = BTreeMap::new();
    // Per function: the ids its instructions use as pointers or callees, and the (storage class,
    // location) of the NV payloads and callable data it names.
    type Uses = (BTreeSet<u32>, BTreeSet<(u32, u32)>);
    let mut functions: BTreeMap<u32, Uses> = BTreeMap::new();
    let mut current: Option<u32> = None;
    for (_, inst) in instructions(words) {
        let count = inst.len();
        let op = inst[0] & 0xFFFF;
        let operand = |k: usize| inst.get(k).copied();
        match op {
            OP_CAPABILITY if count == 2 => {
                out.capabilities.insert(inst[1]);
            }
            OP_EXTENSION => {
                out.extensions.insert(text(&inst[1..]));
            }
            OP_ENTRY_POINT if count >= 4 && entry == NONE => {
                out.model = inst[1];
                entry = inst[2];
            }
            OP_DECORATE if count >= 4 => {
                let d = decorations.entry(inst[1]).or_insert([NONE; 4]);
                match inst[2] {
                    1 => {
                        out.spec_ids.insert(inst[3]);
                    }
                    34 => d[0] = inst[3],
                    33 => d[1] = inst[3],
                    30 => d[2] = inst[3],
                    11 => d[3] = inst[3],
                    _ => {}
                }
            }
            OP_VARIABLE if count >= 4 && current.is_none() => {
                globals.insert(inst[2], inst[3]);
            }
            OP_FUNCTION if count >= 3 => {
                current = Some(inst[2]);
                functions.entry(inst[2]).or_default();
            }
            OP_FUNCTION_END => current = None,
            _ => {
                if let Some(f) = current.and_then(|f| functions.get_mut(&f)) {
                    let (ids, locations) = f;
                    // The operand positions that name a variable (or a callee) per opcode.
                    let named: &[usize] = match op {
                        // OpFunctionCall: the callee and the arguments.
                        OP_FUNCTION_CALL => &[3, 4, 5, 6, 7, 8, 9, 10],
                        // OpImageTexelPointer, OpLoad, OpAccessChain, OpInBoundsAccessChain,
                        // OpPtrAccessChain, OpArrayLength, OpCopyObject: the pointer.
                        60 | 61 | 65 | 66 | 67 | 68 | 83 => &[3],
                        // OpStore, OpCopyMemory, OpCopyMemorySized: the target and the source.
                        62..=64 => &[1, 2],
                        // OpAtomicStore: the pointer.
                        228 => &[1],
                        // The other atomics (load, exchanges, arithmetic, flags): the pointer.
                        227 | 229..=242 | 318 => &[3],
                        319 => &[1],
                        // OpTraceRayKHR: the structure and the payload.
                        4445 => &[1, 11],
                        // OpExecuteCallableKHR: the callable data.
                        4446 => &[2],
                        // OpTraceNV: the structure (the payload is a location, below).
                        OP_TRACE_NV => &[1],
                        _ => &[],
                    };
                    ids.extend(named.iter().filter_map(|&k| operand(k)));
                    match op {
                        OP_TRACE_NV => locations.extend(operand(11).map(|l| (RAY_PAYLOAD, l))),
                        OP_EXECUTE_CALLABLE_NV => {
                            locations.extend(operand(2).map(|l| (CALLABLE_DATA, l)))
                        }
                        _ => {}
                    }
                }
            }
        }
    }
    // The functions the entry point reaches, and what they name.
    let mut reached: BTreeSet<u32> = BTreeSet::new();
    let mut pending = vec![entry];
    let mut used: BTreeSet<u32> = BTreeSet::new();
    while let Some(f) = pending.pop() {
        if !reached.insert(f) {
            continue;
        }
        let Some((ids, locations)) = functions.get(&f) else {
            continue;
        };
        for &id in ids {
            if functions.contains_key(&id) {
                pending.push(id);
            } else if globals.contains_key(&id) {
                used.insert(id);
            }
        }
        for &(class, location) in locations {
            used.extend(globals.iter().filter_map(|(&id, &c)| {
                let d = decorations.get(&id)?;
                (c == class && d[2] == location).then_some(id)
            }));
        }
    }
    for id in used {
        let d = decorations.get(&id).copied().unwrap_or([NONE; 4]);
        out.variables.insert([globals[&id], d[0], d[1], d[2], d[3]]);
    }
    out
}

#[cfg(test)]
mod tests {
    use crate::error::SETUP_COMMAND;

    #[test]
    fn a_disk_entry_is_keyed_by_source_defines_and_stage_and_read_back_only_as_spir_v() {
        let a = super::disk::entry("rgen", "void main() {}", &["TRACE"]);
        let (Some(a), Some(b), Some(c), Some(again)) = (
            a,
            super::disk::entry("rgen", "void main() {}", &[]),
            super::disk::entry("rmiss", "void main() {}", &["TRACE"]),
            super::disk::entry("rgen", "void main() {}", &["TRACE"]),
        ) else {
            // The cache is off in this environment: nothing to key.
            assert_eq!(std::env::var("RTCONF_SPIRV_CACHE").as_deref(), Ok("off"));
            return;
        };
        assert_eq!(a, again);
        assert!(a != b && a != c && b != c, "{a:?} {b:?} {c:?}");
        let dir = tempfile::tempdir().expect("a temporary folder");
        let path = dir.path().join("entry.spv");
        let words = super::compile_glsl(
            "the test shader",
            "rmiss",
            "#version 460\n#extension GL_EXT_ray_tracing : require\nvoid main() {}\n",
            &[],
        )
        .expect("compiles");
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        super::disk::write(&path, &bytes);
        assert_eq!(super::disk::read(&path), Some(words.clone()));
        // Torn or foreign files are not modules: a cut word, a wrong magic number.
        std::fs::write(&path, &bytes[..bytes.len() - 1]).expect("writable");
        assert_eq!(super::disk::read(&path), None);
        let mut foreign = bytes.clone();
        foreign[0] ^= 0xFF;
        std::fs::write(&path, &foreign).expect("writable");
        assert_eq!(super::disk::read(&path), None);
        // Nothing but the entry was left in the folder (the staged file was renamed).
        let left: Vec<_> = std::fs::read_dir(dir.path()).expect("reads").collect();
        assert_eq!(left.len(), 1);
    }

    const ALL: [ShaderKind; 8] = [
        ShaderKind::RaygenTrace,
        ShaderKind::RaygenPlain,
        ShaderKind::Miss,
        ShaderKind::ClosestHitTrace,
        ShaderKind::ClosestHitPlain,
        ShaderKind::AnyHit,
        ShaderKind::Intersection,
        ShaderKind::Callable,
    ];

    use super::*;

    /// A module without what only names its compiler: the generator word and the OpSourceExtension
    /// instructions (opcode 4) shaderc adds for its own preprocessing (`GL_GOOGLE_*`).
    fn without_compiler_marks(words: &[u32]) -> Vec<u32> {
        let mut out = vec![words[0], words[1], words[3], words[4]];
        let mut i = 5;
        while i < words.len() {
            let count = ((words[i] >> 16) as usize).max(1);
            let inst = &words[i..(i + count).min(words.len())];
            let text: Vec<u8> = inst[1..].iter().flat_map(|w| w.to_le_bytes()).collect();
            if !(words[i] & 0xFFFF == 4 && text.starts_with(b"GL_GOOGLE_")) {
                out.extend_from_slice(inst);
            }
            i += count;
        }
        out
    }

    /// Every module build.rs compiled with glslangValidator, compiled again in this process from the
    /// same source and defines: SPIR-V 1.5, and the same instructions, word for word, but for the
    /// marks of the compiler.
    #[test]
    fn in_process_modules_match_the_build_compilers_where_a_driver_reads_them() {
        let checks: [(&str, &str, &str); 5] = [
            (
                "check_query",
                "check_query.comp",
                include_str!("../shaders/check_query.comp"),
            ),
            (
                "check_raygen",
                "check.rgen",
                include_str!("../shaders/check.rgen"),
            ),
            (
                "check_miss",
                "check.rmiss",
                include_str!("../shaders/check.rmiss"),
            ),
            (
                "check_closest_hit",
                "check.rchit",
                include_str!("../shaders/check.rchit"),
            ),
            (
                "check_intersection",
                "check.rint",
                include_str!("../shaders/check.rint"),
            ),
        ];
        let mut variants: Vec<(String, &str, &str, Vec<&str>)> = checks
            .iter()
            .map(|&(name, file, text)| (name.to_string(), file, text, vec![]))
            .collect();
        for k in ALL {
            for api in [ShaderApi::Khr, ShaderApi::Nv] {
                for body in BODIES {
                    let (file, text, args) = k.source();
                    let mut defines: Vec<&str> =
                        args.iter().map(|a| a.trim_start_matches("-D")).collect();
                    if api == ShaderApi::Nv {
                        defines.push("NV");
                    }
                    defines.extend(body.defines());
                    variants.push((k.variant_name(api, body), file, text, defines));
                }
            }
        }
        assert_eq!(variants.len(), PRECOMPILED.len(), "one per build.rs module");
        for (name, file, text, defines) in variants {
            let built = PRECOMPILED
                .iter()
                .find(|(n, _)| *n == name)
                .and_then(|(_, b)| *b)
                .unwrap_or_else(|| {
                    panic!("build.rs compiled {name} (glslangValidator: `{SETUP_COMMAND}`)")
                });
            let built = words(&name, built).unwrap();
            let ext = file.rsplit('.').next().unwrap();
            let here = compile_glsl(&name, ext, text, &defines).unwrap();
            assert_eq!(here[1], 0x0001_0500, "{name}: SPIR-V 1.5");
            assert!(
                without_compiler_marks(&here) == without_compiler_marks(&built),
                "{name}: the same module as glslangValidator's"
            );
        }
    }

    #[test]
    fn a_compile_error_names_the_shader_and_carries_the_message_and_the_source() {
        let text = "#version 460\nvoid main() { undeclared_name = 1; }\n";
        match compile_glsl("the planted shader", "comp", text, &[]) {
            Err(HarnessError::Shader(m)) => {
                assert!(m.contains("the planted shader"), "{m}");
                assert!(m.contains("undeclared_name"), "the compiler's message: {m}");
                assert!(m.contains("error"), "the compiler's message: {m}");
                assert!(m.ends_with(text), "the source: {m}");
            }
            other => panic!("a shader error, got {other:?}"),
        }
        match compile_glsl(
            "the planted shader",
            "frag",
            "#version 460\nvoid main() {}\n",
            &[],
        ) {
            Err(HarnessError::Shader(m)) => assert!(m.contains(".frag"), "{m}"),
            other => panic!("no stage for .frag, got {other:?}"),
        }
    }

    /// A define is what `-DNAME` gives: defined, with an empty value.
    #[test]
    fn a_define_is_defined_empty() {
        let text = "#version 460\nlayout(local_size_x = 1) in;\n#if !defined(PLANTED)\n#error not defined\n#endif\n#define EMPTY_CHECK PLANTED 1\nvoid main() { int a = EMPTY_CHECK; }\n";
        assert!(compile_glsl("defined", "comp", text, &["PLANTED"]).is_ok());
        assert!(matches!(
            compile_glsl("undefined", "comp", text, &[]),
            Err(HarnessError::Shader(m)) if m.contains("not defined")
        ));
    }

    #[test]
    fn every_shader_kind_has_spirv_for_both_apis() {
        const RAY_TRACING_NV: u32 = 5340;
        const RAY_TRACING_KHR: u32 = 4479;
        for (k, api, body) in every_variant() {
            {
                let words = spirv(k, api, body).unwrap();
                assert_eq!(
                    words[0], 0x0723_0203,
                    "{k:?} {api:?} starts with the SPIR-V magic number"
                );
                let caps = module_interface(&words).capabilities;
                let want = if api == ShaderApi::Nv {
                    RAY_TRACING_NV
                } else {
                    RAY_TRACING_KHR
                };
                assert!(
                    caps.contains(&want),
                    "{k:?} {api:?} {body:?} declares capability {want}: {caps:?}"
                );
            }
        }
    }

    /// The default value of each 32-bit specialisation constant of a module, by SpecId (read apart
    /// from `with_spec_values`: every decoration, then the constants they name).
    fn spec_defaults(words: &[u32]) -> BTreeMap<u32, u32> {
        let mut ids = BTreeMap::new();
        let mut values = BTreeMap::new();
        for (_, inst) in instructions(words) {
            match inst[0] & 0xFFFF {
                71 if inst.len() == 4 && inst[2] == 1 => {
                    ids.insert(inst[1], inst[3]);
                }
                50 if inst.len() == 4 => {
                    values.insert(inst[2], inst[3]);
                }
                _ => {}
            }
        }
        ids.into_iter()
            .filter_map(|(id, spec)| values.get(&id).map(|&v| (spec, v)))
            .collect()
    }

    /// Each OpConstant of a module: its result id and value word.
    fn constants(words: &[u32]) -> BTreeMap<u32, u32> {
        instructions(words)
            .filter(|(_, inst)| inst[0] & 0xFFFF == 43 && inst.len() == 4)
            .map(|(_, inst)| (inst[2], inst[3]))
            .collect()
    }

    /// The result id of each specialisation constant by SpecId.
    fn spec_ids(words: &[u32]) -> BTreeMap<u32, u32> {
        instructions(words)
            .filter(|(_, inst)| inst[0] & 0xFFFF == 71 && inst.len() == 4 && inst[2] == 1)
            .map(|(_, inst)| (inst[3], inst[1]))
            .collect()
    }

    #[test]
    fn written_constants_become_ordinary_constants_of_their_values() {
        for (k, api, body) in every_variant() {
            let words = spirv(k, api, body).unwrap();
            let before = spec_defaults(&words);
            let ids = spec_ids(&words);
            // Every stage but the raygen declares the group index; the any-hit shader also its rule.
            let raygen = matches!(k, ShaderKind::RaygenTrace | ShaderKind::RaygenPlain);
            assert_eq!(
                before.contains_key(&0),
                !raygen,
                "{k:?} {api:?} {body:?}: {before:?}"
            );
            assert_eq!(before.contains_key(&1), k == ShaderKind::AnyHit, "{k:?}");
            let out = with_spec_values(&words, &[7, 3]);
            // No specialisation constant is left: each named one is an OpConstant of its value, and
            // its SpecId decoration (four words) is gone.
            assert!(spec_defaults(&out).is_empty(), "{k:?} {api:?} {body:?}");
            assert!(spec_ids(&out).is_empty(), "{k:?} {api:?} {body:?}");
            let frozen = constants(&out);
            for (spec, id) in &ids {
                assert_eq!(
                    frozen.get(id),
                    Some(&[7, 3][*spec as usize]),
                    "{k:?} {spec}"
                );
            }
            assert_eq!(
                out.len(),
                words.len() - 4 * ids.len(),
                "{k:?} {api:?} {body:?}"
            );
            // Everything else is kept, in order: the module's interface but its spec IDs, and every
            // instruction that is not one of the rewritten ones.
            let (a, b) = (module_interface(&words), module_interface(&out));
            assert_eq!(
                (a.model, &a.capabilities, &a.extensions, &a.variables),
                (b.model, &b.capabilities, &b.extensions, &b.variables),
                "{k:?} {api:?} {body:?}"
            );
            let rewritten = |inst: &[u32]| {
                let op = inst[0] & 0xFFFF;
                (op == 71 && inst.len() == 4 && inst[2] == 1)
                    || (matches!(op, 43 | 50) && ids.values().any(|id| inst.get(2) == Some(id)))
            };
            let kept = |w: &[u32]| -> Vec<Vec<u32>> {
                instructions(w)
                    .filter(|(_, inst)| !rewritten(inst))
                    .map(|(_, inst)| inst.to_vec())
                    .collect()
            };
            assert_eq!(kept(&words), kept(&out), "{k:?} {api:?} {body:?}");
            assert_eq!(words[..5], out[..5]);
            // A SpecId the list does not name stays a specialisation constant with its value.
            let partly = with_spec_values(&words, &[9]);
            assert_eq!(spec_defaults(&partly).get(&1), before.get(&1), "{k:?}");
            assert_eq!(spec_defaults(&partly).get(&0), None, "{k:?}");
            if let Some(id) = ids.get(&0) {
                assert_eq!(constants(&partly).get(id), Some(&9), "{k:?}");
            }
        }
    }

    const BODIES: [ShaderBody; 2] = [ShaderBody::Full, ShaderBody::InterfaceOnly];

    fn every_variant() -> Vec<(ShaderKind, ShaderApi, ShaderBody)> {
        ALL.iter()
            .flat_map(|&k| {
                [ShaderApi::Khr, ShaderApi::Nv]
                    .into_iter()
                    .flat_map(move |api| BODIES.map(|b| (k, api, b)))
            })
            .collect()
    }

    /// The trace instructions of a module.
    fn traces(words: &[u32]) -> usize {
        let mut n = 0;
        let mut i = 5;
        while i < words.len() {
            let count = (words[i] >> 16) as usize;
            n += usize::from(matches!(words[i] & 0xFFFF, 4445 | 5337 | 5339));
            i += count.max(1);
        }
        n
    }

    /// The interface-only body of every kind, for both APIs, has the full body's interface, no
    /// trace (its source's traces edited out, the interface the same before and after), and is
    /// smaller where the full body computes anything.
    #[test]
    fn an_interface_only_body_has_the_full_bodys_interface() {
        let mut smaller = 0;
        for k in ALL {
            for api in [ShaderApi::Khr, ShaderApi::Nv] {
                let full = spirv(k, api, ShaderBody::Full).unwrap();
                let only = spirv(k, api, ShaderBody::InterfaceOnly).unwrap();
                let (f, o) = (module_interface(&full), module_interface(&only));
                assert!(
                    !f.variables.is_empty() && f.model != u32::MAX,
                    "{k:?} {api:?}: the interface is read"
                );
                assert_eq!(f, o, "{k:?} {api:?}: the same interface");
                smaller += usize::from(only.len() < full.len());
                assert_eq!(traces(&only), 0, "{k:?} {api:?}: no trace is left");
                if matches!(k, ShaderKind::RaygenTrace | ShaderKind::ClosestHitTrace) {
                    // The interface-only source traces the scene (its load of it stays) and the
                    // full one does: both before the edit.
                    assert!(traces(&full) > 0, "{k:?} {api:?}: the full body traces");
                    let compiled = compile_source(k, api, ShaderBody::InterfaceOnly).unwrap();
                    assert!(traces(&compiled) > 0, "{k:?} {api:?}: its source traces");
                    assert_eq!(
                        module_interface(&compiled),
                        o,
                        "{k:?} {api:?}: the edit keeps it"
                    );
                }
            }
        }
        // Raygen, closest-hit, any-hit and intersection, both variants each where they have two.
        assert!(
            smaller >= 12,
            "{smaller} interface-only modules are smaller"
        );
    }

    /// The reader of interfaces sees a planted difference: a binding the other body does not use.
    #[test]
    fn the_interface_reader_sees_a_binding_used_by_one_body_only() {
        let text = "#version 460\n#extension GL_EXT_ray_tracing : require\n\
            layout(set = 0, binding = 1, std430) buffer A { uint a[]; };\n\
            layout(set = 0, binding = 2, std430) buffer B { uint b[]; };\n\
            void main() {\n#ifdef BOTH\n    b[0] = 1u;\n#endif\n    a[0] = 1u;\n}\n";
        let one = compile_glsl("planted", "rgen", text, &[]).unwrap();
        let both = compile_glsl("planted", "rgen", text, &["BOTH"]).unwrap();
        let (one, both) = (module_interface(&one), module_interface(&both));
        assert_ne!(one, both);
        assert_eq!(one.variables.len() + 1, both.variables.len());
    }
}
