//! Resource accesses in every ray tracing stage, realised on lavapipe under the 1.3.239
//! validation layer: a valid state's accesses placed in each stage a generated launch executes run
//! silently and leave the model's output words; an Unknown-format read placed in each stage draws its
//! rule from the layer (statically used by a bound shader, reached or not); accesses in a stage the
//! pipeline lacks are unsupported; and every stage's templated GLSL compiles for NV pipelines too, its
//! interface-only body with the full body's interface.

mod common;

use common::{body, committed, world, Lavapipe};
use generator::resources::{launch_stages, move_to_stage, valid_state};
use generator::{generate, CaseSpec};
use harness::resource_glsl::{
    compile_stage, module_interface, stage_glsl, stage_source, ShaderBody,
};
use harness::Status;
use model::case::Case;
use model::resources::Stage;
use model::world::PipelineApi;
use model::CommandId;
use std::collections::BTreeMap;

const STAGES: [Stage; 6] = [
    Stage::Raygen,
    Stage::ClosestHit,
    Stage::Miss,
    Stage::AnyHit,
    Stage::Intersection,
    Stage::Callable,
];

fn case(name: &str) -> Case {
    committed(&format!("resources/{name}.yaml"))
}

/// Generated valid launches, one per stage they execute (the first found), for every stage any of
/// them executes.
fn launches_by_stage() -> BTreeMap<Stage, Case> {
    let profile = session::sources::profile_for("lavapipe").expect("profiles/lavapipe.json");
    let rules = generator::registry::default_rules().expect("the installed registry loads");
    let mut out = BTreeMap::new();
    for seed in 0..6 {
        let cases = generate(
            &profile,
            "lavapipe",
            &rules,
            &CaseSpec::valid(CommandId::TraceRays),
            40,
            seed,
        )
        .expect("valid cases");
        for c in cases {
            let t = body(&c);
            if t.world.pipeline.as_ref().map(|p| p.api) != Some(PipelineApi::Khr) {
                continue;
            }
            for s in launch_stages(&t.world, &t.call) {
                out.entry(s).or_insert_with(|| c.clone());
            }
        }
    }
    out
}

#[test]
fn valid_accesses_run_in_every_stage_the_launch_executes() {
    let profile = session::sources::profile_for("lavapipe").expect("profiles/lavapipe.json");
    let launches = launches_by_stage();
    for s in [
        Stage::Raygen,
        Stage::Miss,
        Stage::ClosestHit,
        Stage::Intersection,
        Stage::Callable,
    ] {
        assert!(
            launches.contains_key(&s),
            "no generated launch executes {s:?}"
        );
    }
    let mut lvp = Lavapipe::new();
    for (stage, base) in &launches {
        let mut c = base.clone();
        world(&mut c).resources = valid_state(&profile, 3, 0x1ff);
        move_to_stage(&mut world(&mut c).resources, *stage);
        assert!(launch_stages(&body(&c).world, &body(&c).call).contains(stage));
        let obs = lvp.observe(&c);
        assert_eq!(obs.status, Status::Ran, "{stage:?}: {obs:?}");
        assert!(
            obs.layer_vuids.is_empty(),
            "{stage:?}: {:#?}",
            obs.layer_messages
        );
        assert_records(&c, &obs, &format!("{stage:?}"));
    }
}

#[test]
fn an_unknown_format_read_in_any_bound_stage_draws_its_rule() {
    // The committed 07028 case's pipeline has raygen, miss, procedural hit groups (closest-hit and
    // intersection) and callables; its launch reaches only some of them, and the rule is about static use.
    let mut lvp = Lavapipe::new();
    for stage in [
        Stage::Raygen,
        Stage::Miss,
        Stage::ClosestHit,
        Stage::Intersection,
        Stage::Callable,
    ] {
        let mut c = case("vkCmdTraceRaysIndirectKHR-OpTypeImage-07028-4-0");
        move_to_stage(&mut world(&mut c).resources, stage);
        let obs = lvp.observe(&c);
        assert_eq!(obs.status, Status::Ran, "{stage:?}: {obs:?}");
        assert!(
            obs.layer_vuids
                .iter()
                .any(|v| v.starts_with("VUID-vkCmdTraceRays") && v.ends_with("-07028")),
            "{stage:?}: the layer reported {:?}",
            obs.layer_vuids
        );
    }
}

#[test]
fn accesses_in_a_stage_the_pipeline_lacks_are_not_realised() {
    // The committed cases' pipelines have no any-hit shader.
    let mut c = case("vkCmdTraceRaysIndirectKHR-OpTypeImage-07028-4-0");
    move_to_stage(&mut world(&mut c).resources, Stage::AnyHit);
    let obs = Lavapipe::new().observe(&c);
    match &obs.status {
        Status::NotRealised { reason } => assert!(reason.contains("AnyHit"), "{reason}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn every_stage_template_compiles_for_khr_and_nv() {
    let profile = session::sources::profile_for("lavapipe").expect("profiles/lavapipe.json");
    for stage in STAGES {
        let mut st = valid_state(&profile, 3, 0x1ff);
        move_to_stage(&mut st, stage);
        let (glsl, _) = stage_glsl(&st, stage, stage_source(stage).0).expect("expressible");
        assert!(glsl.contains("layout(set = 1, binding = 0)"), "{stage:?}");
        for api in [PipelineApi::Khr, PipelineApi::Nv] {
            for trace in [false, true] {
                let [full, only] = [ShaderBody::Full, ShaderBody::InterfaceOnly].map(|body| {
                    compile_stage(&glsl, stage, trace, api, body).unwrap_or_else(|e| {
                        panic!("{stage:?} {api:?} trace {trace} {body:?}: {e:?}")
                    })
                });
                assert_eq!(full[0], 0x0723_0203, "{stage:?} {api:?}: SPIR-V magic");
                // The state's accesses are used by both bodies: the layer reads the same module
                // interface (and the set 1 binding is in it).
                let interface = module_interface(&full);
                assert!(
                    interface.variables.iter().any(|v| v[1] == 1),
                    "{stage:?} {api:?} trace {trace}: {interface:?}"
                );
                assert_eq!(
                    interface,
                    module_interface(&only),
                    "{stage:?} {api:?} trace {trace}"
                );
            }
        }
    }
}

#[test]
fn generated_valid_resource_states_run_silently() {
    // The generator's valid states (every access subset, Unknown formats, pushes, atomics) on the
    // valid case's launch: the layer stays silent and the words are the model's.
    let mut lvp = Lavapipe::new();
    let base = case("trace-indirect-valid-resources");
    let mut ran = 0;
    for (choice, bits) in [
        (0, 0x1ff),
        (1, 0x1ff),
        (2, 0x0ff),
        (3, 0x17f),
        (5, 0x041),
        (6, 0x103),
        (7, 0x1ff),
        (11, 0x0a5),
    ] {
        let mut c = base.clone();
        world(&mut c).resources = valid_state(&lvp.profile, choice, bits);
        let obs = lvp.observe(&c);
        assert_eq!(
            obs.status,
            Status::Ran,
            "choice {choice} bits {bits:#x}: {obs:?}"
        );
        assert!(
            obs.layer_vuids.is_empty(),
            "choice {choice} bits {bits:#x}: {:#?}",
            obs.layer_messages
        );
        assert_records(&c, &obs, &format!("choice {choice} bits {bits:#x}"));
        ran += 1;
    }
    assert_eq!(ran, 8);
}

/// The case's records judged by the model: no launch ID breaks what the spec requires.
fn assert_records(c: &model::Case, obs: &harness::Observation, what: &str) {
    let j = model::rendered::judge_records(body(c), obs.words().expect("records read back"))
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    assert_eq!(
        j.result.failures, 0,
        "{what}: {:#?}",
        j.result.first_failures
    );
}
