//! Resource accesses in every ray tracing stage (issue 4), realised on lavapipe under the 1.3.239
//! validation layer: a valid state's accesses placed in each stage a generated launch executes run
//! silently and leave the model's output words; an Unknown-format read placed in each stage draws its
//! rule from the layer (statically used by a bound shader, reached or not); accesses in a stage the
//! pipeline lacks are unsupported; and every stage's templated GLSL compiles for NV pipelines too.

use generator::resources::{launch_stages, move_to_stage, valid_state};
use generator::{generate, CaseSpec, Command};
use harness::resources::{compile_stage, stage_glsl, stage_source};
use harness::{execute, Driver, Executor, Status};
use model::case::Case;
use model::resources::Stage;
use model::world::PipelineApi;
use std::collections::BTreeMap;
use std::path::PathBuf;

const STAGES: [Stage; 6] = [
    Stage::Raygen,
    Stage::ClosestHit,
    Stage::Miss,
    Stage::AnyHit,
    Stage::Intersection,
    Stage::Callable,
];

fn executor() -> Executor {
    Executor::new(Driver::Lavapipe)
        .expect("lavapipe and the validation layer are installed by scripts/setup.sh")
}

fn case(name: &str) -> Case {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../cases/resources")
        .join(format!("{name}.yaml"));
    let text = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    Case::from_yaml(&p.display().to_string(), &text).expect("a case file")
}

/// Generated valid launches, one per stage they execute (the first found), for every stage any of
/// them executes.
fn launches_by_stage() -> BTreeMap<Stage, Case> {
    let profile = generator::profiles::load("lavapipe").expect("profiles/lavapipe.json");
    let rules = generator::registry::default_rules().expect("the installed registry loads");
    let mut out = BTreeMap::new();
    for seed in 0..6 {
        let cases = generate(
            &profile,
            "lavapipe",
            &rules,
            &CaseSpec::valid(Command::TraceRays),
            40,
            seed,
        )
        .expect("valid cases");
        for c in cases {
            if c.world.pipeline.as_ref().map(|p| p.api) != Some(PipelineApi::Khr) {
                continue;
            }
            for s in launch_stages(&c.world, &c.call) {
                out.entry(s).or_insert_with(|| c.clone());
            }
        }
    }
    out
}

#[test]
fn valid_accesses_run_in_every_stage_the_launch_executes() {
    let profile = generator::profiles::load("lavapipe").expect("profiles/lavapipe.json");
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
    let mut ctx = executor();
    for (stage, base) in &launches {
        let mut c = base.clone();
        c.world.resources = valid_state(&profile, 3, 0x1ff);
        move_to_stage(&mut c.world.resources, *stage);
        assert!(launch_stages(&c.world, &c.call).contains(stage));
        let obs = execute(&c, &mut ctx);
        assert_eq!(obs.status, Status::Ran, "{stage:?}: {obs:?}");
        assert!(
            obs.layer_vuids.is_empty(),
            "{stage:?}: {:#?}",
            obs.layer_messages
        );
        let expected = model::semantics::expected_launch(&c.world, &c.call).expect("dimensions");
        assert_eq!(
            obs.output.as_deref(),
            Some(expected.words.as_slice()),
            "{stage:?}"
        );
    }
}

#[test]
fn an_unknown_format_read_in_any_bound_stage_draws_its_rule() {
    // The committed 07028 case's pipeline has raygen, miss, procedural hit groups (closest-hit and
    // intersection) and callables; its launch reaches only some of them, and the rule is about static use.
    let mut ctx = executor();
    for stage in [
        Stage::Raygen,
        Stage::Miss,
        Stage::ClosestHit,
        Stage::Intersection,
        Stage::Callable,
    ] {
        let mut c = case("vkCmdTraceRaysIndirectKHR-OpTypeImage-07028-4-0");
        move_to_stage(&mut c.world.resources, stage);
        let obs = execute(&c, &mut ctx);
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
fn accesses_in_a_stage_the_pipeline_lacks_are_unsupported() {
    // The committed cases' pipelines have no any-hit shader.
    let mut c = case("vkCmdTraceRaysIndirectKHR-OpTypeImage-07028-4-0");
    move_to_stage(&mut c.world.resources, Stage::AnyHit);
    let obs = execute(&c, &mut executor());
    match &obs.status {
        Status::Unsupported { reason } => assert!(reason.contains("AnyHit"), "{reason}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn every_stage_template_compiles_for_khr_and_nv() {
    let profile = generator::profiles::load("lavapipe").expect("profiles/lavapipe.json");
    for stage in STAGES {
        let mut st = valid_state(&profile, 3, 0x1ff);
        move_to_stage(&mut st, stage);
        let (glsl, _) = stage_glsl(&st, stage, stage_source(stage).0).expect("expressible");
        assert!(glsl.contains("layout(set = 1, binding = 0)"), "{stage:?}");
        for api in [PipelineApi::Khr, PipelineApi::Nv] {
            for trace in [false, true] {
                let words = compile_stage(&glsl, stage, trace, api)
                    .unwrap_or_else(|e| panic!("{stage:?} {api:?} trace {trace}: {e:?}"));
                assert_eq!(words[0], 0x0723_0203, "{stage:?} {api:?}: SPIR-V magic");
            }
        }
    }
}
