//! Hand-made cases shared by the lavapipe tests and the worker-pool tests, and how they are run.

use model::call::{Address, Call, StridedRegion};
use model::case::{Case, Intent};
use model::world::*;

pub fn at(buffer: &str, offset: u64) -> Address {
    Address::InBuffer {
        buffer: buffer.into(),
        offset,
    }
}

/// The hand-made valid case (`cases/hand/trace-indirect-records-32.yaml`): raygen + two miss groups +
/// one triangle hit group; records laid out at shaderGroupBaseAlignment (32); three rays (hit the
/// triangle, miss with index 0, miss with index 1); an indirect 4x2x1 launch.
pub fn valid_case() -> Case {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../cases/hand/trace-indirect-records-32.yaml");
    let text = std::fs::read_to_string(&path).expect("the hand-made case");
    Case::from_yaml(&path.display().to_string(), &text).expect("the hand-made case parses")
}

/// The valid case with its miss stride broken (40 is not a multiple of shaderGroupHandleAlignment 16).
#[allow(dead_code)] // used by the worker tests only
pub fn bad_miss_stride_case() -> Case {
    let mut case = valid_case();
    case.name = "bad-miss-stride".into();
    if let Some(Call::TraceRaysIndirect(c)) = case.as_trace_mut().map(|t| &mut t.call) {
        c.miss.stride = 40;
        c.miss.size = 80;
    }
    case.intent = Intent::Violates {
        vuid: "VUID-vkCmdTraceRaysIndirectKHR-stride-03686".into(),
        also: vec![],
    };
    case
}

/// A direct 3x2x1 launch whose raygen executes callable records 1 and 0 and whose closest-hit traces its ray
/// twice more (extra_recursion 2, maxPipelineRayRecursionDepth 3): raygen, miss, triangle hit, two callable
/// groups; rays hit the triangle, miss with index 0, miss with index 1.
#[allow(dead_code)] // used by the lavapipe tests only
pub fn recursive_callable_case() -> Case {
    let mut case = valid_case();
    case.name = "hand-made-callables-recursion".into();
    let t = case.as_trace_mut().expect("a trace case");
    let w = &mut t.world;
    w.buffers[0].contents.push(Contents::ShaderRecords {
        offset: 192,
        stride: 32,
        handles: vec![HandleRef::Group(4), HandleRef::Group(5)],
    });
    let p = w.pipeline.as_mut().expect("the valid case has a pipeline");
    p.groups.push(ShaderGroup::General {
        stage: GeneralStage::Callable,
    });
    p.groups.push(ShaderGroup::General {
        stage: GeneralStage::Callable,
    });
    p.max_recursion_depth = 3;
    w.launch.callables = vec![1, 0];
    w.launch.extra_recursion = 2;
    let Call::TraceRaysIndirect(c) = &t.call else {
        unreachable!()
    };
    t.call = Call::TraceRays(model::call::TraceRays {
        raygen: c.raygen.clone(),
        miss: c.miss.clone(),
        hit: c.hit.clone(),
        callable: StridedRegion {
            address: at("sbt", 192),
            stride: 32,
            size: 64,
        },
        width: 3,
        height: 2,
        depth: 1,
    });
    case
}

/// The trace body of a hand-made case.
#[allow(dead_code)]
pub fn body(case: &Case) -> &model::TraceBody {
    case.as_trace().expect("a trace case")
}

/// The world of a hand-made case, to edit.
#[allow(dead_code)]
pub fn world(case: &mut Case) -> &mut World {
    &mut case.as_trace_mut().expect("a trace case").world
}

/// The call of a hand-made case, to edit.
#[allow(dead_code)]
pub fn call(case: &mut Case) -> &mut Call {
    &mut case.as_trace_mut().expect("a trace case").call
}

/// Runs a case as a run would: the undefined-reads gate first, then for real when it is valid,
/// recorded only otherwise.
#[allow(dead_code)]
pub fn execute(case: &Case, ex: &mut harness::Executor) -> harness::Observation {
    case.runnable(lavapipe())
        .unwrap_or_else(|e| panic!("{}: {e}", case.name));
    ex.execute(case, &harness::Execution::for_case(case, lavapipe()))
}

/// A runner for the tests: lavapipe with the validation layer.
#[allow(dead_code)]
pub fn executor() -> harness::Executor {
    harness::Executor::new(harness::Driver::Lavapipe)
        .expect("lavapipe and the validation layer are installed by scripts/setup.sh")
}

/// A committed case by path under `cases/`.
#[allow(dead_code)]
pub fn committed(path: &str) -> Case {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../cases")
        .join(path);
    let text = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    Case::from_yaml(&p.display().to_string(), &text).expect("a case file")
}

/// The lavapipe profile the hand-made cases are for.
fn lavapipe() -> &'static model::DeviceProfile {
    static PROFILE: std::sync::OnceLock<model::DeviceProfile> = std::sync::OnceLock::new();
    PROFILE.get_or_init(|| {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../profiles/lavapipe.json");
        let text = std::fs::read_to_string(p).expect("profiles/lavapipe.json");
        model::DeviceProfile::from_profiles_json("lavapipe", &text).expect("a profile")
    })
}

/// A valid case's records judged by the model (`model::rendered`): panics naming the first failures.
#[allow(dead_code)] // not every test file judges records
pub fn assert_records(case: &Case, obs: &harness::Observation) -> model::rendered::LaunchJudgement {
    let words = obs
        .words()
        .unwrap_or_else(|| panic!("{}: no records read back: {obs:?}", case.name));
    let j = model::rendered::judge_records(case.as_trace().expect("a trace case"), words)
        .unwrap_or_else(|e| panic!("{}: {e}", case.name));
    assert_eq!(
        j.result.failures, 0,
        "{}: {:#?}",
        case.name, j.result.first_failures
    );
    j
}

/// The (outcome, group) each launch ID's record names.
#[allow(dead_code)]
pub fn outcomes(obs: &harness::Observation) -> Vec<(u32, u32)> {
    let w = obs.words().expect("records");
    w.chunks(model::tracer::record::RayRecord::WORDS)
        .map(|r| (r[0], r[1]))
        .collect()
}
