//! 64-bit image accesses (VUID-vkCmdTraceRays*-SampledType-04470..04473): the generator's worlds on a
//! device with VK_EXT_shader_image_atomic_int64 — the committed NVIDIA profile with the extension's
//! feature reported and the R64 formats given what the extension requires of them (storage image and
//! storage image atomics) and lavapipe's captured texel buffer features — are judged by the model as
//! exactly their VUID, their shaders compile for KHR and NV pipelines, and the harness refuses none of
//! them (on lavapipe they stop at the device, which lacks the extension). The one lavapipe can express
//! (a 32-bit fetch of an R64 uniform texel buffer) runs there under the layer with no other VUID. The
//! committed lavapipe profile makes the cases unsupported; what is still not realised says why.

mod common;

use common::{body, executor, world};
use generator::{generate, CaseSpec, GenError};
use harness::observe::DeviceLack;
use harness::resource_glsl::{compile_stage, stage_glsl, stage_source, ShaderBody};
use harness::Status;
use model::case::{Case, Intent};
use model::resources::{Numeric, Op};
use model::world::PipelineApi;
use model::{CommandId, DeviceProfile};
use std::collections::BTreeSet;

const EXTENSION: &str = "VK_EXT_shader_image_atomic_int64";
const TAGS: [&str; 4] = ["04470", "04471", "04472", "04473"];

fn committed_profile(name: &str) -> DeviceProfile {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../profiles")
        .join(format!("{name}.json"));
    let text = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    DeviceProfile::from_profiles_json(name, &text).expect("a profile")
}

/// The NVIDIA profile as a probe that records the extension's feature structure and the R64 formats
/// would capture it: shaderImageInt64Atomics reported; R64_UINT and R64_SINT with the optimal-tiling
/// bits the extension requires, and the buffer features lavapipe reports for them.
fn int64_profile() -> DeviceProfile {
    let mut p = committed_profile("nvidia-h200");
    assert!(p.has_extension(EXTENSION), "the H200 reports {EXTENSION}");
    p.features.insert(
        "VkPhysicalDeviceShaderImageAtomicInt64FeaturesEXT::shaderImageInt64Atomics".into(),
        true,
    );
    let lvp = committed_profile("lavapipe");
    for f in ["VK_FORMAT_R64_UINT", "VK_FORMAT_R64_SINT"] {
        let mut ff = lvp
            .formats
            .get(f)
            .cloned()
            .expect("lavapipe's probe records R64");
        ff.optimal_tiling = [
            "VK_FORMAT_FEATURE_STORAGE_IMAGE_BIT",
            "VK_FORMAT_FEATURE_STORAGE_IMAGE_ATOMIC_BIT",
        ]
        .map(String::from)
        .into();
        p.formats.insert(f.into(), ff);
    }
    p
}

fn rules() -> &'static model::rules::RuleSet {
    static RULES: std::sync::OnceLock<model::rules::RuleSet> = std::sync::OnceLock::new();
    RULES.get_or_init(|| generator::registry::default_rules().expect("the installed registry"))
}

fn vuid(command: CommandId, tag: &str) -> String {
    format!("VUID-{}-SampledType-{tag}", command.vk_name())
}

fn cases(profile: &DeviceProfile, command: CommandId, tag: &str) -> Vec<Case> {
    generate(
        profile,
        "nvidia-h200-int64",
        rules(),
        &CaseSpec::violate(command, &vuid(command, tag)),
        6,
        11,
    )
    .unwrap_or_else(|e| panic!("{}: {e}", vuid(command, tag)))
}

/// The 64-bit access of a case (the last access of the stage that has accesses).
fn wide_access(c: &Case) -> (model::resources::Stage, model::resources::Access) {
    let st = &body(c).world.resources;
    let s = st
        .stages
        .iter()
        .find(|s| !s.accesses.is_empty())
        .expect("a stage with accesses");
    (
        s.stage,
        s.accesses.last().cloned().expect("the mutation's access"),
    )
}

#[test]
fn the_worlds_are_exactly_their_vuid_and_their_shaders_compile() {
    let profile = int64_profile();
    let mut checked = 0;
    for command in CommandId::TRACE {
        for tag in TAGS {
            let target = vuid(command, tag);
            let mut ops = BTreeSet::new();
            for c in cases(&profile, command, tag) {
                let got: BTreeSet<String> = model::validate(rules(), &profile, &c)
                    .vuids()
                    .into_iter()
                    .map(String::from)
                    .collect();
                assert_eq!(got, BTreeSet::from([target.clone()]), "{}", c.to_yaml());
                assert_eq!(
                    c.intent,
                    Intent::Violates {
                        vuid: target.clone(),
                        also: vec![]
                    }
                );
                let (stage, a) = wide_access(&c);
                let t = a.image.expect("an image access");
                assert_ne!(t.sampled_type, Numeric::Float, "{target}: an integer type");
                let wide_type = matches!(tag, "04471" | "04473");
                assert_eq!(t.width == 64, wide_type, "{target}");
                let dev = &body(&c).world.device;
                assert_eq!(
                    dev.feature("shaderImageInt64Atomics") && dev.feature("shaderInt64"),
                    wide_type,
                    "{target}: the features follow the shader's types"
                );
                ops.insert(format!("{:?}", a.op));
                let st = &body(&c).world.resources;
                let (glsl, _) = stage_glsl(st, stage, stage_source(stage).0)
                    .unwrap_or_else(|e| panic!("{target}: {e:?}"));
                assert_eq!(
                    glsl.contains("GL_EXT_shader_image_int64"),
                    wide_type,
                    "{target}"
                );
                let api = body(&c).world.pipeline.as_ref().expect("a pipeline").api;
                assert_eq!(api == PipelineApi::Nv, command.is_nv());
                for trace in [false, true] {
                    for shader_body in [ShaderBody::Full, ShaderBody::InterfaceOnly] {
                        let words = compile_stage(&glsl, stage, trace, api, shader_body)
                            .unwrap_or_else(|e| panic!("{target} {stage:?}: {e:?}\n{glsl}"));
                        assert_eq!(words[0], 0x0723_0203, "{target}: SPIR-V magic");
                    }
                }
                checked += 1;
            }
            // The 64-bit-format rules read through storage (Unknown format) and fetch alike.
            if tag == "04472" {
                assert!(ops.contains("Fetch"), "{target}: {ops:?}");
            }
        }
    }
    assert_eq!(checked, 3 * 4 * 6);
}

#[test]
fn the_harness_refuses_none_of_them_and_lavapipe_lacks_the_extension() {
    let profile = int64_profile();
    let mut ctx = executor();
    for command in [CommandId::TraceRays, CommandId::TraceRaysIndirect] {
        for tag in TAGS {
            let c = cases(&profile, command, tag).remove(0);
            let obs = ctx.execute(&c, &harness::Execution::for_case(&c, &profile));
            match &obs.status {
                Status::Unsupported {
                    lacks: DeviceLack::Extension(e),
                    ..
                } => assert_eq!(e, EXTENSION, "{}", c.name),
                other => panic!("{}: {other:?}", c.name),
            }
        }
    }
}

#[test]
fn a_fetch_of_a_64_bit_texel_buffer_runs_on_lavapipe_with_no_other_vuid() {
    // Lavapipe reports UNIFORM_TEXEL_BUFFER_BIT for the R64 formats but not the extension, which a
    // 32-bit fetch does not need; the 1.3.239 registry's condition of 04472 names it, so the cases are
    // generated as if lavapipe had it and run with it taken out of the world.
    let lvp = committed_profile("lavapipe");
    let mut as_if = lvp.clone();
    as_if.extensions.insert(EXTENSION.into());
    let mut ctx = executor();
    let mut ran = 0;
    for command in [CommandId::TraceRays, CommandId::TraceRaysIndirect] {
        let target = vuid(command, "04472");
        for mut c in cases(&as_if, command, "04472") {
            assert_eq!(wide_access(&c).1.op, Op::Fetch, "{}", c.name);
            world(&mut c).device.extensions.remove(EXTENSION);
            let obs = ctx.execute(&c, &harness::Execution::for_case(&c, &lvp));
            assert_eq!(obs.status, Status::Ran, "{}: {obs:?}", c.name);
            // The 1.3.239 layer has no check of 04472 (1.4.309 reports it): nothing else may appear.
            assert!(
                obs.layer_vuids.iter().all(|v| *v == target),
                "{}: {:#?}",
                c.name,
                obs.layer_messages
            );
            ran += 1;
        }
    }
    assert_eq!(ran, 2 * 6);
}

#[test]
fn on_the_committed_lavapipe_profile_the_cases_are_unsupported() {
    let lvp = committed_profile("lavapipe");
    for command in [CommandId::TraceRays, CommandId::TraceRaysIndirect] {
        for tag in TAGS {
            let v = vuid(command, tag);
            match generate(
                &lvp,
                "lavapipe",
                rules(),
                &CaseSpec::violate(command, &v),
                2,
                1,
            ) {
                Err(GenError::Unsupported(why)) => assert!(
                    why.contains("condition") || why.contains(EXTENSION) || why.contains("64-bit"),
                    "{v}: {why}"
                ),
                other => panic!("{v}: {other:?}"),
            }
        }
    }
}

#[test]
fn what_is_not_realised_says_why() {
    let profile = int64_profile();
    let mut ctx = executor();
    let base = cases(&profile, CommandId::TraceRays, "04471").remove(0);
    let (stage, _) = wide_access(&base);
    fn last(c: &mut Case, stage: model::resources::Stage) -> &mut model::resources::Access {
        world(c)
            .resources
            .stages
            .iter_mut()
            .find(|s| s.stage == stage)
            .and_then(|s| s.accesses.last_mut())
            .expect("the access")
    }
    let not_realised = |c: &Case, ctx: &mut harness::Executor| match ctx
        .execute(c, &harness::Execution::for_case(c, &profile))
        .status
    {
        Status::NotRealised { reason } => reason,
        other => panic!("{}: {other:?}", c.name),
    };
    // Without the feature the Int64ImageEXT capability needs.
    let mut c = base.clone();
    world(&mut c)
        .device
        .features
        .remove("shaderImageInt64Atomics");
    let why = not_realised(&c, &mut ctx);
    assert!(why.contains("shaderImageInt64Atomics"), "{why}");
    // A 64-bit float Sampled Type.
    let mut c = base.clone();
    last(&mut c, stage).image.as_mut().unwrap().sampled_type = Numeric::Float;
    let why = not_realised(&c, &mut ctx);
    assert!(why.contains("64-bit float"), "{why}");
    // A known Image Format whose width is not the Sampled Type's.
    let mut c = base.clone();
    last(&mut c, stage).image.as_mut().unwrap().format_unknown = false;
    let why = not_realised(&c, &mut ctx);
    assert!(why.contains("04965"), "{why}");
}
