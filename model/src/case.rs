//! A case: the unit that is generated, judged, executed, reported, shrunk and replayed — one serde type
//! for every command, written as YAML a person can read and edit.
//!
//! ```yaml
//! name: trace-indirect-basic
//! profile: lavapipe
//! intent: valid
//! command: vkCmdTraceRaysIndirectKHR
//! world: { ... }   # the world of the command: a trace world, or a build world
//! call: { ... }    # the call's parameters
//! ```
//!
//! `command` comes before `world` and `call`, since it says what they are.

use crate::accel::{BuildIndirect, BuildWorld};
use crate::call::Call;
use crate::command::CommandId;
use crate::profile::DeviceProfile;
use crate::world::{CommandBufferState, DeviceState, World};

/// What a case is meant to be.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub enum Intent {
    /// Valid by construction: the verdict must be empty.
    Valid,
    /// Violates exactly `vuid`, plus the declared co-violations that the device makes unavoidable.
    Violates {
        vuid: String,
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        also: Vec<String>,
    },
}

/// A trace call and the world it is made in.
#[derive(Debug, Clone, PartialEq)]
pub struct TraceBody {
    pub world: World,
    pub call: Call,
}

impl TraceBody {
    /// What the launch's scene and rays leave undefined (`Scene::undefined`), with paths in the case
    /// file (`world.launch.scene.instances[2].transform`, `world.launch.rays[3].tmin`).
    pub fn scene_problems(&self) -> Vec<crate::scene::Problem> {
        let launch = &self.world.launch;
        let rays = launch.ray_list();
        launch
            .scene
            .undefined(&rays)
            .into_iter()
            .map(|mut p| {
                p.path = match p.path.strip_prefix("rays[") {
                    Some(rest) => {
                        let (index, tail) = rest.split_once(']').unwrap_or((rest, ""));
                        match index.parse::<usize>() {
                            Ok(i) if i < launch.rays.len() => {
                                format!("world.launch.rays[{i}]{tail}")
                            }
                            Ok(i) => {
                                let field = tail.trim_start_matches('.');
                                let ray = i - launch.rays.len();
                                p.message = format!("camera ray {ray}: {}", p.message);
                                match field {
                                    "origin" => "world.launch.camera.eye".into(),
                                    "" | "direction" => "world.launch.camera".into(),
                                    f => format!("world.launch.camera.{f}"),
                                }
                            }
                            Err(_) => format!("world.launch.{}", p.path),
                        }
                    }
                    None => format!("world.launch.{}", p.path),
                };
                p
            })
            .collect()
    }
}

/// An acceleration structure build call and the world it is made in.
#[derive(Debug, Clone, PartialEq)]
pub struct AccelBody {
    pub world: BuildWorld,
    pub call: BuildIndirect,
}

/// What a case calls, per command family.
#[derive(Debug, Clone, PartialEq)]
#[allow(clippy::large_enum_variant)] // a case holds one body; boxing it would only add an indirection
pub enum Body {
    Trace(TraceBody),
    Accel(AccelBody),
}

/// A generated or hand-written case.
#[derive(Debug, Clone, PartialEq)]
pub struct Case {
    pub name: String,
    /// The device profile it was made for (`lavapipe`, `nvidia-h100`, or a path).
    pub profile: String,
    /// The proptest seed that produced it, when generated.
    pub seed: Option<String>,
    pub intent: Intent,
    pub body: Body,
}

/// A case file that could not be read, or that is not a case (see [`crate::integrity`]): the file, the
/// line and column, the YAML path of what is wrong, and what is: `file:line:col: path: problem`.
#[derive(Debug, thiserror::Error)]
#[error(
    "{path}{}: {}{problem}",
    location.map(|(l, c)| format!(":{l}:{c}")).unwrap_or_default(),
    if at.is_empty() { String::new() } else { format!("{at}: ") }
)]
pub struct CaseError {
    pub path: String,
    pub location: Option<(usize, usize)>,
    /// The YAML path of the value at fault (`world.buffers[0].contents[1].handles[0]`); empty when the
    /// text itself does not parse there.
    pub at: String,
    pub problem: String,
}

/// Why a case must not be handed to a driver: what a valid case's scene or rays leave undefined,
/// what its launch would read that is undefined, or a build run as valid the model gives no meaning to
/// check the device against. Each is the case's fault, never the driver's.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{}", self.describe())]
pub struct NotRunnable {
    /// The YAML path of what makes it so (`call.miss`, a range record of `world.buffers`, the first
    /// undefined thing of the scene).
    pub at: String,
    /// Undefined things of the scene and rays (`Scene::undefined`), their paths in the case file.
    pub scene: Vec<crate::scene::Problem>,
    pub reads: Vec<String>,
}

impl NotRunnable {
    fn describe(&self) -> String {
        let mut parts = Vec::new();
        if !self.scene.is_empty() {
            parts.push(format!(
                "the valid case's scene is undefined: {}",
                self.scene
                    .iter()
                    .map(|p| p.to_string())
                    .collect::<Vec<_>>()
                    .join("; ")
            ));
        }
        parts.extend(self.reads.iter().cloned());
        parts.join("; ")
    }

    /// Each problem as `file:line:col: path: problem` (line and column located in the case file's
    /// `text`), then the undefined reads.
    pub fn located(&self, file: &str, text: &str) -> Vec<String> {
        let mut out: Vec<String> = self
            .scene
            .iter()
            .map(|p| {
                let at = crate::locate::locate(text, &p.path)
                    .map(|(l, c)| format!(":{l}:{c}"))
                    .unwrap_or_default();
                format!("{file}{at}: {}: {}", p.path, p.message)
            })
            .collect();
        out.extend(self.reads.iter().map(|r| format!("{file}: {r}")));
        out
    }
}

/// The longest case name: a run keeps a case as `NAME.yaml` and its pictures as `NAME-expected.png`
/// and the like, which must stay within a file system's 255 bytes.
pub const MAX_NAME_LEN: usize = 200;

/// Why `name` cannot be a case's name, where it cannot. A run keeps a case's file and pictures under
/// its name in the run's folders, so the name is one file name of ASCII letters, digits, `.`, `_`,
/// `+` and `-`, not starting with `.` (no `/` to leave the folder by, no `..`, nothing hidden), 1 to
/// [`MAX_NAME_LEN`] bytes. Every generated name and every committed case's is one.
pub fn name_problem(name: &str) -> Option<String> {
    let allowed = |c: char| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '+' | '-');
    let problem = if name.is_empty() {
        "is empty".to_string()
    } else if name.len() > MAX_NAME_LEN {
        format!("is {} bytes long, more than {MAX_NAME_LEN}", name.len())
    } else if let Some(c) = name.chars().find(|&c| !allowed(c)) {
        format!("holds {c:?}")
    } else if name.starts_with('.') {
        "starts with `.`".to_string()
    } else {
        return None;
    };
    Some(format!(
        "the case name {problem}: a run keeps the case as NAME.yaml in its folders, so a name is \
         ASCII letters, digits, `.`, `_`, `+` and `-`, not starting with `.`, at most {MAX_NAME_LEN} bytes"
    ))
}

/// The deepest nesting of flow collections (`[...]`, `{...}`) a YAML input may have. The YAML
/// scanner's time grows with the square of this nesting, and no case or triage file needs more than a
/// few levels.
pub const MAX_FLOW_NESTING: usize = 64;

/// The most bytes read from one case or triage file: a generated case is a few kilobytes, a
/// rendered scene's of a hundred thousand triangles some ten megabytes.
pub const YAML_FILE_LIMIT: u64 = 64 * vk_registry::input::MIB;

/// The line and column (from 1) of the first flow collection (`[...]`, `{...}`) that opens more than
/// `limit` levels deep; None when none does, or when the text stops being YAML before one does (the
/// reader then reports that error).
///
/// The YAML parser itself finds it, event by event, and is stopped there: what is a bracket of a flow
/// collection, and what is text of a quoted, plain or block scalar or of a comment, is the parser's own
/// reading, so no layout of quotes or lines hides a level from the count. Its scanner spends time in
/// proportion to the open flow levels on every token, so a parse run to the end of deeply nested input
/// takes time growing with the square of the nesting; stopped past `limit`, it stays linear.
pub fn flow_nesting_past(text: &str, limit: usize) -> Option<(usize, usize)> {
    use std::mem::MaybeUninit;
    use unsafe_libyaml as unsafe_yaml;

    /// The parser, deleted when dropped; boxed, as the parser keeps pointers into itself.
    struct Parser(Box<MaybeUninit<unsafe_yaml::yaml_parser_t>>);
    impl Drop for Parser {
        fn drop(&mut self) {
            // SAFETY: initialised in `flow_nesting_past` before this value was made.
            unsafe { unsafe_yaml::yaml_parser_delete(self.0.as_mut_ptr()) }
        }
    }

    let mut boxed = Box::new(MaybeUninit::<unsafe_yaml::yaml_parser_t>::uninit());
    // SAFETY: `yaml_parser_initialize` writes the whole parser; on failure (no memory) nothing was
    // allocated and the parser is not used.
    if unsafe { unsafe_yaml::yaml_parser_initialize(boxed.as_mut_ptr()) }.fail {
        return None;
    }
    let mut parser = Parser(boxed);
    let p = parser.0.as_mut_ptr();
    // SAFETY: the parser is initialised; the input outlives it (`parser` is dropped before `text`
    // goes out of scope), and the parser only reads it.
    unsafe {
        unsafe_yaml::yaml_parser_set_encoding(p, unsafe_yaml::YAML_UTF8_ENCODING);
        unsafe_yaml::yaml_parser_set_input_string(p, text.as_ptr(), text.len() as u64);
    }
    // Flow collections hold no block collections, so every collection inside a flow one is flow too:
    // the flow depth is all the state needed.
    let mut depth = 0usize;
    loop {
        let mut event = MaybeUninit::<unsafe_yaml::yaml_event_t>::uninit();
        // SAFETY: the parser is initialised, and no call follows a failed one (the loop ends there);
        // on success the event is initialised, read, then deleted once.
        let (kind, flow_start, mark) = unsafe {
            if unsafe_yaml::yaml_parser_parse(p, event.as_mut_ptr()).fail {
                return None;
            }
            let e = event.assume_init_mut();
            let flow_start = match e.type_ {
                unsafe_yaml::YAML_SEQUENCE_START_EVENT => {
                    e.data.sequence_start.style == unsafe_yaml::YAML_FLOW_SEQUENCE_STYLE
                }
                unsafe_yaml::YAML_MAPPING_START_EVENT => {
                    e.data.mapping_start.style == unsafe_yaml::YAML_FLOW_MAPPING_STYLE
                }
                _ => false,
            };
            let out = (e.type_, flow_start, e.start_mark);
            unsafe_yaml::yaml_event_delete(e);
            out
        };
        match kind {
            unsafe_yaml::YAML_STREAM_END_EVENT => return None,
            unsafe_yaml::YAML_SEQUENCE_START_EVENT | unsafe_yaml::YAML_MAPPING_START_EVENT
                if depth > 0 || flow_start =>
            {
                depth += 1;
                if depth > limit {
                    return Some((mark.line as usize + 1, mark.column as usize + 1));
                }
            }
            unsafe_yaml::YAML_SEQUENCE_END_EVENT | unsafe_yaml::YAML_MAPPING_END_EVENT
                if depth > 0 =>
            {
                depth -= 1
            }
            _ => {}
        }
    }
}

/// Parses any serde type from YAML, reporting the line and column of what is wrong.
pub fn parse_yaml<T: serde::de::DeserializeOwned>(path: &str, text: &str) -> Result<T, CaseError> {
    if let Some(location) = flow_nesting_past(text, MAX_FLOW_NESTING) {
        return Err(CaseError {
            path: path.to_string(),
            location: Some(location),
            at: String::new(),
            problem: format!(
                "flow collections ([...] or {{...}}) nested deeper than {MAX_FLOW_NESTING} levels"
            ),
        });
    }
    serde_yaml::from_str(text).map_err(|e| {
        // serde_yaml says where only what it read: a second document gets no line, so find it (its
        // `---`), or else the error that made libyaml start one.
        let (location, message) = match e.location() {
            Some(l) => (Some((l.line(), l.column())), e.to_string()),
            None => match second_document(text) {
                Some(line) => (Some((line, 1)), e.to_string()),
                None => match unreadable_document(text) {
                    Some((location, message)) => (Some(location), message),
                    None => (None, e.to_string()),
                },
            },
        };
        let (at, problem) = split_message(&message);
        CaseError {
            path: path.to_string(),
            location,
            at,
            problem,
        }
    })
}

/// The located error of the first document of `text` that does not read as YAML, and its message.
/// Where a node ends early (an anchor or a tag with nothing after it, then more on the line),
/// libyaml starts a second document without a `---`, and serde_yaml refuses the text as several
/// documents without saying where; read one document at a time, the one that fails says it.
fn unreadable_document(text: &str) -> Option<((usize, usize), String)> {
    use serde::Deserialize;
    for document in serde_yaml::Deserializer::from_str(text) {
        if let Err(e) = serde::de::IgnoredAny::deserialize(document) {
            let l = e.location()?;
            return Some(((l.line(), l.column()), e.to_string()));
        }
    }
    None
}

/// serde_yaml's message `path: problem at line L column C` as (path, problem): the position is said
/// once, before them.
fn split_message(message: &str) -> (String, String) {
    let message = match message.rfind(" at line ") {
        Some(i) if message[i..].contains(" column ") => &message[..i],
        _ => message,
    };
    match message.split_once(": ") {
        Some((path, rest))
            if !path.is_empty()
                && path
                    .chars()
                    .all(|c| c.is_alphanumeric() || "_-.[]".contains(c)) =>
        {
            (path.to_string(), rest.to_string())
        }
        _ => (String::new(), message.to_string()),
    }
}

/// The line (from 1) where a second YAML document starts: a `---` after content or after another
/// `---` (the first document empty), or the first content after a `...` end marker.
fn second_document(text: &str) -> Option<usize> {
    // A document has begun: its `---`, or content.
    let mut begun = false;
    let mut ended = false;
    for (i, line) in text.lines().enumerate() {
        let starts_document =
            line == "---" || line.starts_with("--- ") || line.starts_with("---\t");
        if starts_document {
            if begun || ended {
                return Some(i + 1);
            }
            begun = true;
            continue;
        }
        if line == "..." || line.starts_with("... ") {
            ended = begun;
            continue;
        }
        let blank = line.trim().is_empty() || line.trim_start().starts_with('#');
        if !blank && !line.starts_with('%') {
            if ended {
                return Some(i + 1);
            }
            begun = true;
        }
    }
    None
}

impl Intent {
    /// The VUIDs a verdict must hold for this intent, sorted.
    pub fn expected_vuids(&self) -> Vec<String> {
        match self {
            Intent::Valid => vec![],
            Intent::Violates { vuid, also } => {
                let mut v: Vec<String> = std::iter::once(vuid.clone())
                    .chain(also.iter().cloned())
                    .collect();
                v.sort();
                v.dedup();
                v
            }
        }
    }

    /// The VUID an invalid case targets.
    pub fn target(&self) -> Option<&str> {
        match self {
            Intent::Valid => None,
            Intent::Violates { vuid, .. } => Some(vuid),
        }
    }
}

impl Body {
    pub fn command(&self) -> CommandId {
        match self {
            Body::Trace(t) => t.call.command(),
            Body::Accel(_) => CommandId::BuildAccelerationStructuresIndirect,
        }
    }

    /// The device state the world enables.
    pub fn device(&self) -> &DeviceState {
        match self {
            Body::Trace(t) => &t.world.device,
            Body::Accel(a) => &a.world.device,
        }
    }

    /// The command buffer the call is recorded into.
    pub fn command_buffer(&self) -> &CommandBufferState {
        match self {
            Body::Trace(t) => &t.world.command_buffer,
            Body::Accel(a) => &a.world.command_buffer,
        }
    }
}

impl Case {
    /// A case of a trace call.
    pub fn trace(name: &str, profile: &str, intent: Intent, world: World, call: Call) -> Case {
        Case {
            name: name.into(),
            profile: profile.into(),
            seed: None,
            intent,
            body: Body::Trace(TraceBody { world, call }),
        }
    }

    /// A case of an acceleration structure build.
    pub fn accel(
        name: &str,
        profile: &str,
        intent: Intent,
        world: BuildWorld,
        call: BuildIndirect,
    ) -> Case {
        Case {
            name: name.into(),
            profile: profile.into(),
            seed: None,
            intent,
            body: Body::Accel(AccelBody { world, call }),
        }
    }

    /// Parses a case from YAML, reporting the line and column of what is wrong.
    pub fn from_yaml(path: &str, text: &str) -> Result<Case, CaseError> {
        parse_yaml(path, text)
    }

    /// Reads a case file as every command that takes one does: parsed ([`Case::from_yaml`]), then
    /// refused with a name that cannot be a file's ([`name_problem`]) or the first of its own errors
    /// ([`crate::integrity::flaws`]), located in the file.
    pub fn read(path: &str, text: &str) -> Result<Case, CaseError> {
        let case = Case::from_yaml(path, text)?;
        if let Some(problem) = name_problem(&case.name) {
            return Err(CaseError {
                path: path.to_string(),
                location: crate::locate::locate(text, "name"),
                at: "name".into(),
                problem,
            });
        }
        let flaws = crate::integrity::flaws(&case);
        match flaws.first() {
            None => Ok(case),
            Some(f) => Err(CaseError {
                path: path.to_string(),
                location: crate::locate::locate(text, &f.at),
                at: f.at.clone(),
                problem: match flaws.len() {
                    1 => f.problem.clone(),
                    n => format!("{} (and {} more error(s) of the case)", f.problem, n - 1),
                },
            }),
        }
    }

    /// The case's YAML, its sequences of numbers and names on one line each and a ray or a box as one
    /// flow mapping ([`crate::compact`]); written by [`crate::case_yaml`], which falls back to
    /// serde_yaml and `compact` for what it does not know.
    pub fn to_yaml(&self) -> String {
        crate::case_yaml::write(self)
    }

    pub fn command(&self) -> CommandId {
        self.body.command()
    }

    /// The trace body, for a trace case.
    pub fn as_trace(&self) -> Option<&TraceBody> {
        match &self.body {
            Body::Trace(t) => Some(t),
            Body::Accel(_) => None,
        }
    }

    pub fn as_trace_mut(&mut self) -> Option<&mut TraceBody> {
        match &mut self.body {
            Body::Trace(t) => Some(t),
            Body::Accel(_) => None,
        }
    }

    /// The build body, for an acceleration structure case.
    pub fn as_accel(&self) -> Option<&AccelBody> {
        match &self.body {
            Body::Accel(a) => Some(a),
            Body::Trace(_) => None,
        }
    }

    pub fn as_accel_mut(&mut self) -> Option<&mut AccelBody> {
        match &mut self.body {
            Body::Accel(a) => Some(a),
            Body::Trace(_) => None,
        }
    }

    /// The VUIDs the case expects its verdict to hold, sorted.
    pub fn expected_vuids(&self) -> Vec<String> {
        self.intent.expected_vuids()
    }

    /// Whether the case is run for real (submitted, its output read back and checked): valid, or
    /// violating only what the device makes unavoidable ([`crate::accel::unavoidable`]: a build on a
    /// device without `accelerationStructureIndirectBuild`).
    pub fn runs_as_valid(&self, profile: &DeviceProfile) -> bool {
        match &self.body {
            Body::Trace(_) => self.intent == Intent::Valid,
            Body::Accel(_) => {
                let unavoidable = crate::accel::unavoidable(profile);
                self.expected_vuids()
                    .iter()
                    .all(|v| unavoidable.contains(v))
            }
        }
    }

    /// The undefined-reads gate: a valid case never hands undefined behaviour to a driver. A valid trace
    /// case whose launch reads outside its tables (or reads a record nothing wrote) is not runnable, nor
    /// is a build run as valid whose primitives the model cannot build (they are what the device's
    /// build is checked against); every path that gives a case to a driver (run, replay, tests) asks
    /// this first. Invalid cases are never submitted, so they are runnable.
    pub fn runnable(&self, profile: &DeviceProfile) -> Result<(), NotRunnable> {
        match &self.body {
            Body::Trace(t) if self.intent == Intent::Valid => {
                let scene = t.scene_problems();
                if !scene.is_empty() {
                    // The reads of an undefined scene are not computed: the tracer refuses it.
                    return Err(NotRunnable {
                        at: scene[0].path.clone(),
                        scene,
                        reads: vec![],
                    });
                }
                // The launch traced whole once, here: its misses give the records it reads, and a
                // run's judgement of the records finds it kept (`crate::expected`).
                if let Some(e) = crate::expected::of(&t.world, &t.call) {
                    // The records it may reach, from the same outcomes where they tell them.
                    crate::semantics::prime_hit_reach(&t.world, &t.call, &e);
                }
                let reads = crate::semantics::undefined_reads(
                    crate::semantics::handle_size(profile),
                    &t.world,
                    &t.call,
                );
                if reads.is_empty() {
                    Ok(())
                } else {
                    Err(NotRunnable {
                        at: "call".into(),
                        scene: vec![],
                        reads: reads
                            .into_iter()
                            .map(|r| format!("the valid launch has an undefined read: {r}"))
                            .collect(),
                    })
                }
            }
            Body::Accel(a) if self.runs_as_valid(profile) => {
                let mem = a.world.memory();
                for i in 0..a.call.infos.len() {
                    let built = crate::accel::indirect_ranges(&mem, &a.call, i).and_then(|r| {
                        crate::accel::build_primitives(&mem, &a.call.infos[i], &r).map(|_| r)
                    });
                    if let Err(e) = built {
                        let at = crate::accel::largest_range_record(&a.world, &a.call, i)
                            .filter(|_| e.problem.contains("more than the model builds"))
                            .unwrap_or_else(|| format!("call.infos[{i}]"));
                        return Err(NotRunnable {
                            at,
                            scene: vec![],
                            reads: vec![format!(
                                "the model gives the build no meaning to check the device against: {e}"
                            )],
                        });
                    }
                }
                Ok(())
            }
            _ => Ok(()),
        }
    }
}

mod serial {
    //! The YAML form of a case: `command` first, then the world and the call of that command.

    use super::*;
    use crate::call::{TraceRays, TraceRaysIndirect, TraceRaysNv};
    use serde::de::{self, MapAccess, Visitor};
    use serde::ser::SerializeMap;

    impl serde::Serialize for Case {
        fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
            let mut m = s.serialize_map(None)?;
            m.serialize_entry("name", &self.name)?;
            m.serialize_entry("profile", &self.profile)?;
            if let Some(seed) = &self.seed {
                m.serialize_entry("seed", seed)?;
            }
            m.serialize_entry("intent", &self.intent)?;
            m.serialize_entry("command", &self.command())?;
            match &self.body {
                Body::Trace(t) => {
                    m.serialize_entry("world", &t.world)?;
                    match &t.call {
                        Call::TraceRaysIndirect(c) => m.serialize_entry("call", c)?,
                        Call::TraceRays(c) => m.serialize_entry("call", c)?,
                        Call::TraceRaysNv(c) => m.serialize_entry("call", c)?,
                    }
                }
                Body::Accel(a) => {
                    m.serialize_entry("world", &a.world)?;
                    m.serialize_entry("call", &a.call)?;
                }
            }
            m.end()
        }
    }

    /// The keys of a case (an unknown key is reported where it stands).
    #[derive(serde::Deserialize)]
    #[serde(field_identifier, rename_all = "snake_case")]
    enum Field {
        Name,
        Profile,
        Seed,
        Intent,
        Command,
        World,
        Call,
    }

    /// A value that is out of place: read as an error located where the value stands.
    struct Misplaced(&'static str);

    impl<'de> de::DeserializeSeed<'de> for Misplaced {
        type Value = ();
        fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
            d.deserialize_any(self)
        }
    }

    impl<'de> Visitor<'de> for Misplaced {
        type Value = ();
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            write!(f, "`command` before `{}`", self.0)
        }
        fn visit_map<A: MapAccess<'de>>(self, _: A) -> Result<(), A::Error> {
            Err(de::Error::custom(format!(
                "`command` must come before `{}` (it says which world and call follow)",
                self.0
            )))
        }
    }

    /// The world of either family, read once the command is known.
    #[allow(clippy::large_enum_variant)] // one per case file, read and consumed at once
    enum AnyWorld {
        Trace(World),
        Accel(BuildWorld),
    }

    /// The call of either family, read once the command is known.
    enum AnyCall {
        Trace(Call),
        Accel(BuildIndirect),
    }

    struct CaseVisitor;

    impl<'de> Visitor<'de> for CaseVisitor {
        type Value = Case;

        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("a case: name, profile, seed, intent, command, world and call")
        }

        fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Case, A::Error> {
            let mut name = None;
            let mut profile = None;
            let mut seed = None;
            let mut intent = None;
            let mut command: Option<CommandId> = None;
            let mut world: Option<AnyWorld> = None;
            let mut call: Option<AnyCall> = None;
            while let Some(key) = map.next_key::<Field>()? {
                match key {
                    Field::Name => name = Some(map.next_value()?),
                    Field::Profile => profile = Some(map.next_value()?),
                    Field::Seed => seed = map.next_value()?,
                    Field::Intent => intent = Some(map.next_value()?),
                    Field::Command => command = Some(map.next_value()?),
                    Field::World => {
                        let Some(c) = command else {
                            map.next_value_seed(Misplaced("world"))?;
                            return Err(de::Error::custom("`command` must come before `world`"));
                        };
                        world = Some(if c.is_trace() {
                            AnyWorld::Trace(map.next_value()?)
                        } else {
                            AnyWorld::Accel(map.next_value()?)
                        });
                    }
                    Field::Call => {
                        let Some(c) = command else {
                            map.next_value_seed(Misplaced("call"))?;
                            return Err(de::Error::custom("`command` must come before `call`"));
                        };
                        call = Some(match c {
                            CommandId::TraceRaysIndirect => AnyCall::Trace(
                                Call::TraceRaysIndirect(map.next_value::<TraceRaysIndirect>()?),
                            ),
                            CommandId::TraceRays => {
                                AnyCall::Trace(Call::TraceRays(map.next_value::<TraceRays>()?))
                            }
                            CommandId::TraceRaysNv => {
                                AnyCall::Trace(Call::TraceRaysNv(map.next_value::<TraceRaysNv>()?))
                            }
                            CommandId::BuildAccelerationStructuresIndirect => {
                                AnyCall::Accel(map.next_value()?)
                            }
                        });
                    }
                }
            }
            let body = match (
                world.ok_or_else(|| de::Error::missing_field("world"))?,
                call.ok_or_else(|| de::Error::missing_field("call"))?,
            ) {
                (AnyWorld::Trace(world), AnyCall::Trace(call)) => {
                    Body::Trace(TraceBody { world, call })
                }
                (AnyWorld::Accel(world), AnyCall::Accel(call)) => {
                    Body::Accel(AccelBody { world, call })
                }
                _ => unreachable!("the world and the call are read for the same command"),
            };
            Ok(Case {
                name: name.ok_or_else(|| de::Error::missing_field("name"))?,
                profile: profile.ok_or_else(|| de::Error::missing_field("profile"))?,
                seed,
                intent: intent.ok_or_else(|| de::Error::missing_field("intent"))?,
                body,
            })
        }
    }

    impl<'de> serde::Deserialize<'de> for Case {
        fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Case, D::Error> {
            d.deserialize_map(CaseVisitor)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_case_name_is_one_safe_file_name() {
        for good in [
            "trace-indirect-valid-1-0",
            "VkStridedDeviceAddressRegionKHR-size-04631-2-0",
            "a.b_c+d",
        ] {
            assert_eq!(name_problem(good), None, "{good}");
        }
        let long = "x".repeat(MAX_NAME_LEN + 1);
        for (bad, said) in [
            ("../../tmp/x", "holds '/'"),
            ("..", "starts with `.`"),
            (".hidden", "starts with `.`"),
            ("", "is empty"),
            ("a\\b", "holds '\\\\'"),
            ("tab\there", "holds '\\t'"),
            ("naïve", "holds 'ï'"),
            (long.as_str(), "is 201 bytes long"),
        ] {
            let p = name_problem(bad).unwrap_or_default();
            assert!(
                p.starts_with(&format!("the case name {said}")),
                "{bad:?}: {p}"
            );
        }
    }

    const TRACE: &str = "name: t\nprofile: lavapipe\nintent: valid\ncommand: vkCmdTraceRaysKHR\n\
        world:\n  device: {}\n  pipeline: null\n  command_buffer: { pool_queue: [COMPUTE_BIT] }\n\
        call:\n  raygen: { address: 0, stride: 0, size: 0 }\n  miss: { address: 0, stride: 0, size: 0 }\n\
        \x20 hit: { address: 0, stride: 0, size: 0 }\n  callable: { address: 0, stride: 0, size: 0 }\n\
        \x20 width: 1\n  height: 1\n  depth: 1\n";

    #[test]
    fn a_case_round_trips_through_yaml_with_its_command_first() {
        let c = Case::from_yaml("t.yaml", TRACE).unwrap();
        assert_eq!(c.command(), CommandId::TraceRays);
        let yaml = c.to_yaml();
        let command_at = yaml.find("command:").unwrap();
        assert!(command_at < yaml.find("world:").unwrap(), "{yaml}");
        assert_eq!(Case::from_yaml("again", &yaml).unwrap(), c);
    }

    #[test]
    fn misplaced_and_unknown_fields_are_located_errors() {
        let late =
            TRACE.replace("command: vkCmdTraceRaysKHR\n", "") + "command: vkCmdTraceRaysKHR\n";
        let e = Case::from_yaml("late.yaml", &late).unwrap_err();
        assert!(
            e.problem.contains("`command` must come before `world`"),
            "{e}"
        );
        assert_eq!(e.location.map(|l| l.0), Some(5), "{e}");
        let unknown = TRACE.replace("intent: valid", "intent: valid\ncolour: blue");
        let e = Case::from_yaml("unknown.yaml", &unknown).unwrap_err();
        assert!(e.problem.contains("colour"), "{e}");
        assert_eq!(e.location.map(|l| l.0), Some(4), "{e}");
    }

    /// A text libyaml reads as several documents is refused where the second starts: at its `---`,
    /// or, without one, where the node before it ended early (an anchor with nothing after it).
    #[test]
    fn a_second_document_is_located_with_or_without_its_marker() {
        let cases = [
            ("a: 1\n---\nb: 2\n", (2, 1)),
            ("&a *a", (1, 4)),
            ("&a \n&a \nentries: []", (2, 1)),
            ("entries: []\n...\nmore: 1\n", (3, 1)),
            ("---\n---\nentries: []", (2, 1)),
            ("%YAML 1.2\n---\n# none\n---\nentries: []", (4, 1)),
        ];
        for (text, at) in cases {
            let e = parse_yaml::<serde_yaml::Value>("two.yaml", text).unwrap_err();
            assert_eq!(e.location, Some(at), "{text:?}: {e}");
            assert!(
                e.to_string()
                    .starts_with(&format!("two.yaml:{}:{}: ", at.0, at.1)),
                "{e}"
            );
        }
        // Anchors and aliases inside one document still read.
        let one: serde_yaml::Value = parse_yaml("one.yaml", "a: &x [1]\nb: *x\n").unwrap();
        assert_eq!(one["b"], one["a"]);
        assert_eq!(one["a"][0].as_u64(), Some(1));
    }
}
