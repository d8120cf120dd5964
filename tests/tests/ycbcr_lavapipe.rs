//! Sampler Y′CbCr conversions on the real lavapipe under the real validation layer: the generated
//! cases of the Y′CbCr rules (06550, 06551) of both KHR trace commands are realised and judged as a run
//! judges them — none fails, none is left not realised — and their valid counterpart (the same world
//! sampling without an offset) runs silently and writes what the model expects. The layer checks at
//! object creation that the view of a multi-planar format carries a conversion
//! (VUID-VkImageViewCreateInfo-format-06415) and that the immutable sampler's conversion is the
//! view's (VUID-VkWriteDescriptorSet-descriptorType-01948, -02738), so a silent valid case shows
//! both objects were made with it.

use generator::CaseSpec;
use model::resources::Op;
use model::{CommandId, Intent};
use rtconf_tests::Lavapipe;
use session::Outcome;

const COMMANDS: [CommandId; 2] = [CommandId::TraceRays, CommandId::TraceRaysIndirect];

/// The generated cases of `command`'s rule ending in `tag`.
fn cases(lvp: &Lavapipe, command: CommandId, tag: &str) -> Vec<model::Case> {
    let vuid = lvp
        .rules
        .rows
        .iter()
        .find(|r| r.scope == command.vk_name() && r.vuid.ends_with(tag))
        .unwrap_or_else(|| panic!("{} has a rule {tag}", command.vk_name()))
        .vuid
        .clone();
    generator::generate(
        &lvp.profile,
        "lavapipe",
        &lvp.rules,
        &CaseSpec::violate(command, &vuid),
        4,
        11,
    )
    .unwrap_or_else(|e| panic!("{vuid}: {e:?}"))
}

fn ycbcr_views(c: &model::Case) -> usize {
    let st = &c.as_trace().expect("a trace case").world.resources;
    st.image_views.iter().filter(|v| v.ycbcr_conversion).count()
}

/// Makes a 06551 case valid: its samples through the Y′CbCr combined image sampler lose their offset.
fn sample_without_offset(c: &mut model::Case) {
    c.intent = Intent::Valid;
    let st = &mut c.as_trace_mut().unwrap().world.resources;
    let binding = st
        .set_layouts
        .iter()
        .flat_map(|l| &l.bindings)
        .find(|b| !b.immutable_samplers.is_empty())
        .expect("a binding with an immutable sampler")
        .binding;
    let mut n = 0;
    for a in st.stages.iter_mut().flat_map(|s| s.accesses.iter_mut()) {
        if a.binding == binding && a.offset {
            assert_eq!(a.op, Op::Sample, "06551's cases sample");
            a.offset = false;
            n += 1;
        }
    }
    assert_eq!(n, 1, "{}: one sample with an offset", c.name);
}

#[test]
fn ycbcr_cases_are_realised_and_agree_with_the_model_or_the_triage() {
    let mut lvp = Lavapipe::new();
    let mut bad = vec![];
    let mut n = 0;
    for command in COMMANDS {
        for tag in ["-06550", "-06551"] {
            for c in cases(&lvp, command, tag) {
                assert_eq!(ycbcr_views(&c), 1, "{}: one Y′CbCr view", c.name);
                let r = lvp.run(&c);
                n += 1;
                if !matches!(r.outcome, Outcome::Pass | Outcome::Triaged) {
                    bad.push(format!("{}: {:?} {}", r.case, r.outcome, r.detail));
                }
            }
        }
    }
    assert_eq!(n, 16);
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

#[test]
fn the_valid_counterpart_samples_silently_and_writes_what_the_model_expects() {
    let mut lvp = Lavapipe::new();
    for command in COMMANDS {
        for mut c in cases(&lvp, command, "-06551") {
            c.name = format!("{}-valid", c.name);
            sample_without_offset(&mut c);
            let r = lvp.run(&c);
            assert_eq!(r.outcome, Outcome::Pass, "{}: {}", r.case, r.detail);
            assert!(r.model.is_empty() && r.layer.is_empty(), "{r:?}");
            assert!(r.layer_other.is_empty(), "{}: {:?}", r.case, r.layer_other);
            assert_eq!(r.output_matches, Some(true), "{}: {}", r.case, r.detail);
        }
    }
}

#[test]
fn a_ycbcr_view_without_an_immutable_ycbcr_sampler_is_not_realised() {
    let mut lvp = Lavapipe::new();
    let mut c = cases(&lvp, CommandId::TraceRays, "-06551").remove(0);
    sample_without_offset(&mut c);
    let st = &mut c.as_trace_mut().unwrap().world.resources;
    for b in st
        .set_layouts
        .iter_mut()
        .flat_map(|l| l.bindings.iter_mut())
    {
        b.immutable_samplers.clear();
    }
    let r = lvp.run(&c);
    assert_eq!(r.outcome, Outcome::NotRealised, "{r:?}");
    assert!(r.detail.contains("immutable"), "{}", r.detail);
}
