//! How the model reads the VUID texts whose earlier readings a layer disagreed with, each test saying
//! the reading: recursion depth counts traces only, and closest-hit shaders trace again only where a ray
//! runs one (03679); 03511 speaks of the handle at the miss region's address, not of records rays reach;
//! 09600 names sampled, storage and QCOM images and input attachments, not combined image samplers.

use model::resources::{DescriptorType, ResourceRule};
use model::rules::predicate::Predicate;
use model::rules::RuleSet;
use model::world::{GeneralStage, HandleRef, ShaderGroup};
use model::{Case, DeviceProfile};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn lavapipe() -> DeviceProfile {
    let p = root().join("profiles/lavapipe.json");
    DeviceProfile::from_profiles_json("lavapipe", &std::fs::read_to_string(p).unwrap()).unwrap()
}

fn rules() -> RuleSet {
    RuleSet::from_vuids(
        &vk_registry::source::load_vuids(Path::new(vk_registry::source::DEFAULT_REGISTRY_DIR))
            .expect("the installed registry"),
    )
}

/// The hand-made valid case: raygen, two miss groups, a triangle hit group with closest-hit; ray 0 hits
/// the triangle, rays 1 and 2 miss.
fn base() -> Case {
    let p = root().join("cases/hand/trace-indirect-records-32.yaml");
    Case::from_yaml("base", &std::fs::read_to_string(p).unwrap()).unwrap()
}

fn vuids(rules: &RuleSet, case: &Case) -> Vec<String> {
    rules
        .judge(&lavapipe(), &case.body)
        .vuids()
        .into_iter()
        .map(String::from)
        .collect()
}

const RECURSION: &str = "VUID-vkCmdTraceRaysIndirectKHR-maxPipelineRayRecursionDepth-03679";
const NULL_MISS: &str = "VUID-vkCmdTraceRaysIndirectKHR-flags-03511";

#[test]
fn recursion_depth_counts_closest_hits_that_trace_again_only_where_one_runs() {
    let rules = rules();
    // Closest-hit shaders trace once more (depth 2) under a pipeline allowing 1: ray 0 runs one.
    let mut c = base();
    c.as_trace_mut().unwrap().world.launch.extra_recursion = 1;
    assert!(vuids(&rules, &c).contains(&RECURSION.to_string()));
    // Every ray misses: no closest-hit runs, nothing traces again, the depth reached is 1.
    c.as_trace_mut().unwrap().world.launch.rays[0].origin = [-1000.0, -1000.0, -1.0];
    let t = c.as_trace().unwrap();
    assert_eq!(model::semantics::recursion_depth(&t.world, &t.call), 1);
    assert!(!vuids(&rules, &c).contains(&RECURSION.to_string()), "{c:?}");
    // The hit group has no closest-hit shader: the hit runs none, so none traces again.
    let mut c = base();
    let w = &mut c.as_trace_mut().unwrap().world;
    w.launch.extra_recursion = 1;
    w.pipeline.as_mut().unwrap().groups[3] = ShaderGroup::TrianglesHit {
        closest_hit: false,
        any_hit: false,
        any_hit_rule: Default::default(),
    };
    assert!(!vuids(&rules, &c).contains(&RECURSION.to_string()));
}

#[test]
fn callables_do_not_deepen_the_recursion() {
    let rules = rules();
    let mut c = base();
    let w = &mut c.as_trace_mut().unwrap().world;
    // No ray is traced; raygen executes a callable; the pipeline allows no recursion at all.
    w.launch.rays.clear();
    w.launch.scene = Default::default();
    w.launch.callables = vec![0];
    let p = w.pipeline.as_mut().unwrap();
    p.groups.push(ShaderGroup::General {
        stage: GeneralStage::Callable,
    });
    p.max_recursion_depth = 0;
    assert_eq!(w.launch.recursion_depth(), 0);
    assert!(!vuids(&rules, &c).contains(&RECURSION.to_string()));
}

#[test]
fn null_miss_speaks_of_the_handle_at_the_miss_region_address() {
    let rules = rules();
    let no_null_miss = model::flags::PipelineCreate::RAY_TRACING_NO_NULL_MISS_SHADERS_BIT_KHR;
    let set_record = |c: &mut Case, index: usize, h: HandleRef| {
        let w = &mut c.as_trace_mut().unwrap().world;
        let sbt = w.buffers.iter_mut().find(|b| b.name == "sbt").unwrap();
        for content in &mut sbt.contents {
            if let model::world::Contents::ShaderRecords {
                offset: 64,
                handles,
                ..
            } = content
            {
                handles[index] = h;
            }
        }
    };
    let mut c = base();
    c.as_trace_mut()
        .unwrap()
        .world
        .pipeline
        .as_mut()
        .unwrap()
        .flags
        .insert(no_null_miss);
    assert!(!vuids(&rules, &c).contains(&NULL_MISS.to_string()));
    // Record 0 is zero and no ray misses into it: the handle at the address is zero all the same.
    set_record(&mut c, 0, HandleRef::Zero);
    c.as_trace_mut()
        .unwrap()
        .world
        .launch
        .rays
        .retain(|r| r.miss_index == 1);
    assert!(vuids(&rules, &c).contains(&NULL_MISS.to_string()));
    // Record 1 is zero and a ray misses into it: not the handle at the address, not this VUID.
    let mut c = base();
    c.as_trace_mut()
        .unwrap()
        .world
        .pipeline
        .as_mut()
        .unwrap()
        .flags
        .insert(no_null_miss);
    set_record(&mut c, 1, HandleRef::Zero);
    assert!(!vuids(&rules, &c).contains(&NULL_MISS.to_string()));
}

/// The 1.4.309 registry from trixie, fetched with scripts/fetch-registry.sh when missing.
fn registry_1_4_309() -> PathBuf {
    let dest = root().join("target/registry/1.4.309");
    let reg = dest.join("usr/share/vulkan/registry");
    if !reg.join("validusage.json").exists() {
        let status = std::process::Command::new("bash")
            .arg(root().join("scripts/fetch-registry.sh"))
            .arg(&dest)
            .status()
            .expect("running scripts/fetch-registry.sh");
        assert!(status.success(), "scripts/fetch-registry.sh failed");
    }
    reg
}

#[test]
fn image_layout_rule_names_the_descriptor_types_its_text_lists() {
    let set = vk_registry::source::load_vuids(&registry_1_4_309()).expect("the 1.4.309 registry");
    let rules = RuleSet::from_vuids(&set);
    let row = rules
        .row("VUID-vkCmdTraceRaysKHR-None-09600")
        .expect("1.4.309 has 09600");
    let Some(Predicate::Resource(ResourceRule::LayoutMatches { types })) = &row.predicate else {
        panic!("09600 is the layout rule: {:?}", row.predicate);
    };
    assert!(types.contains(&DescriptorType::SampledImage));
    assert!(types.contains(&DescriptorType::StorageImage));
    assert!(types.contains(&DescriptorType::InputAttachment));
    assert!(
        !types.contains(&DescriptorType::CombinedImageSampler),
        "the text does not list combined image samplers: {types:?}"
    );
}

/// 08606 opens "If the shaderObject feature is not enabled", 08607 "If the shaderObject feature is
/// enabled": with no pipeline bound, a device without shaderObject violates 08606 only.
#[test]
fn no_pipeline_bound_is_08606_without_shader_object_and_08607_with_it() {
    let set = vk_registry::source::load_vuids(&registry_1_4_309()).expect("the 1.4.309 registry");
    let rules = RuleSet::from_vuids(&set);
    let not_enabled = "VUID-vkCmdTraceRaysIndirectKHR-None-08606";
    let enabled = "VUID-vkCmdTraceRaysIndirectKHR-None-08607";
    for (v, want) in [(not_enabled, false), (enabled, true)] {
        let row = rules.row(v).expect("1.4.309 has the VUID");
        assert_eq!(
            row.predicate,
            Some(Predicate::PipelineBoundWhenShaderObject(want)),
            "{v}"
        );
    }
    let mut c = base();
    c.as_trace_mut()
        .unwrap()
        .world
        .command_buffer
        .pipeline_bound = false;
    let got = vuids(&rules, &c);
    assert!(got.contains(&not_enabled.to_string()), "{got:?}");
    assert!(!got.contains(&enabled.to_string()), "{got:?}");
    c.as_trace_mut()
        .unwrap()
        .world
        .device
        .features
        .insert("shaderObject".into());
    let got = vuids(&rules, &c);
    assert!(got.contains(&enabled.to_string()), "{got:?}");
    assert!(!got.contains(&not_enabled.to_string()), "{got:?}");
}
