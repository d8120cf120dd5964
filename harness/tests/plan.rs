//! The call plan against the model it is made from, with no device: every committed build case's
//! memory images, laid out from the plan with any addresses, are the model's own images with those
//! addresses. The call plan does not describe trace cases (rendered scenes) yet: every committed trace
//! case is refused with that reason, and the buffer plans the trace executor realises write its shader
//! records and indirect commands where the world says.

use harness::plan::trace::{buffer_plans, BufferWrite, NOT_DESCRIBED};
use harness::plan::{CallPlan, PlanBody, Step};
use harness::Execution;
use model::accel::world::{AddressResolver, SyntheticAddresses};
use model::world::Contents;
use model::Case;
use std::path::Path;

fn committed(folder: &str) -> Vec<Case> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../cases")
        .join(folder);
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "yaml"))
        .collect();
    files.sort();
    files
        .iter()
        .map(|p| {
            let text = std::fs::read_to_string(p).unwrap();
            Case::from_yaml(&p.display().to_string(), &text).unwrap()
        })
        .collect()
}

/// Addresses unlike the model's synthetic ones: buffer `k` at `0x1_0000 * (k + 3)`, structure `s` at
/// `0x7000_0000 + 0x100 * s`.
struct Elsewhere<'w>(&'w model::accel::BuildWorld);

impl AddressResolver for Elsewhere<'_> {
    fn buffer(&self, name: &str) -> Option<u64> {
        let k = self.0.buffers.iter().position(|b| b.name == name)?;
        Some(0x1_0000 * (k as u64 + 3))
    }
    fn structure(&self, name: &str) -> Option<u64> {
        let s = self.0.structures.iter().position(|x| x.name == name)?;
        Some(0x7000_0000 + 0x100 * s as u64)
    }
}

#[test]
fn build_plans_lay_out_the_models_memory_images_at_any_addresses() {
    let cases = committed("build");
    assert!(cases.len() >= 40, "{} build cases", cases.len());
    let mut relocated = 0;
    for case in &cases {
        let body = case.as_accel().expect("a build case");
        let plan = CallPlan::of(case, &Execution::default()).expect("a plan");
        let PlanBody::Build(b) = &plan.body else {
            panic!("{}: not a build plan", case.name)
        };
        assert_eq!(b.buffers.len(), body.world.buffers.len());
        for buffer in &b.buffers {
            relocated += buffer.relocations.len();
            let synthetic = SyntheticAddresses(&body.world);
            let elsewhere = Elsewhere(&body.world);
            for r in [&synthetic as &dyn AddressResolver, &elsewhere] {
                assert_eq!(
                    buffer.image_at(r),
                    body.world.image(&buffer.name, r).unwrap(),
                    "{}: buffer {}",
                    case.name,
                    buffer.name
                );
            }
        }
        let calls = b
            .steps
            .iter()
            .filter(|s| matches!(s, Step::Call { .. }))
            .count();
        assert_eq!(calls, 1, "{}: one call", case.name);
    }
    assert!(relocated > 0, "some committed case holds device addresses");
}

#[test]
fn trace_cases_are_refused_by_the_call_plan_and_their_buffers_written_where_the_world_says() {
    let mut cases = committed("hand");
    cases.extend(committed("edge"));
    cases.extend(committed("rendered"));
    for case in &cases {
        let body = case.as_trace().expect("a trace case");
        let exec = Execution {
            run_valid: case.intent == model::Intent::Valid,
            ..Default::default()
        };
        match CallPlan::of(case, &exec) {
            Err(harness::HarnessError::NotRealised(why)) => {
                assert_eq!(why, NOT_DESCRIBED, "{}", case.name);
                assert!(
                    why.contains("does not yet describe rendered-scene trace cases"),
                    "{why}"
                );
            }
            other => panic!("{}: {other:?}", case.name),
        }
        let buffers = buffer_plans(&body.world);
        assert_eq!(buffers.len(), body.world.buffers.len(), "{}", case.name);
        for (b, world) in buffers.iter().zip(&body.world.buffers) {
            assert_eq!(b.name, world.name);
            assert_eq!(b.size, world.size);
            let handles: usize = world
                .contents
                .iter()
                .map(|c| match c {
                    Contents::ShaderRecords { handles, .. } => handles.len(),
                    _ => 0,
                })
                .sum();
            let written = b
                .writes
                .iter()
                .filter(|w| matches!(w, BufferWrite::Handle { .. }))
                .count();
            assert_eq!(handles, written, "{}: {}", case.name, b.name);
            for w in &b.writes {
                if let BufferWrite::Handle { offset, handle } = w {
                    assert_eq!(
                        body.world.handle_at(&b.name, *offset),
                        Some(*handle),
                        "{}: {} at {offset}",
                        case.name,
                        b.name
                    );
                }
            }
        }
    }
}
