//! The resource rules on hand-made worlds: formats read from their names, format features from the
//! profile (derived bits included), and the wording variants between versions judged as worded.

use model::resources::formats::{self, Usage};
use model::resources::rules::ResourceRule;
use model::resources::*;
use model::DeviceProfile;

fn lavapipe() -> DeviceProfile {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../profiles/lavapipe.json");
    DeviceProfile::from_profiles_json("lavapipe", &std::fs::read_to_string(p).unwrap()).unwrap()
}

#[test]
fn formats_are_read_from_their_names() {
    let i = formats::info("VK_FORMAT_R8G8B8A8_UNORM").unwrap();
    assert_eq!(
        (i.numeric, i.components, i.width, i.depth),
        (Numeric::Float, 4, 8, false)
    );
    let i = formats::info("VK_FORMAT_R64_UINT").unwrap();
    assert_eq!((i.numeric, i.components, i.width), (Numeric::Uint, 1, 64));
    let i = formats::info("VK_FORMAT_X8_D24_UNORM_PACK32").unwrap();
    assert_eq!((i.components, i.depth), (1, true));
    assert_eq!(formats::info("VK_FORMAT_A8_UNORM").unwrap().components, 1);
    assert_eq!(
        formats::info("VK_FORMAT_R32G32_SINT").unwrap().numeric,
        Numeric::Int
    );
    assert!(formats::info("VK_FORMAT_BC1_RGB_UNORM_BLOCK").is_none());
}

#[test]
fn format_features_come_from_the_profile_with_derived_bits() {
    let p = lavapipe();
    let f = formats::features(&p, "VK_FORMAT_R32_UINT", Usage::Optimal).unwrap();
    assert!(f.contains("STORAGE_IMAGE_ATOMIC_BIT"));
    // lavapipe supports shaderStorageImageReadWithoutFormat, and R32_UINT storage images.
    assert!(f.contains("STORAGE_READ_WITHOUT_FORMAT_BIT"));
    let f = formats::features(&p, "VK_FORMAT_R32G32B32_SFLOAT", Usage::Optimal).unwrap();
    assert!(
        !f.contains("STORAGE_READ_WITHOUT_FORMAT_BIT"),
        "no storage, so no storage without format"
    );
    assert!(
        formats::features(&p, "VK_FORMAT_D32_SFLOAT", Usage::Optimal).is_none(),
        "unreported: unknown"
    );
}

#[test]
fn a_resource_state_round_trips_through_yaml_and_empty_states_are_not_written() {
    let st = ResourceState {
        samplers: vec![Sampler {
            name: "s".into(),
            mag_filter: Filter::Linear,
            ..Default::default()
        }],
        stages: vec![StageUse {
            stage: Stage::Raygen,
            accesses: vec![Access {
                binding: 1,
                op: Op::Write,
                texel_components: Some(2),
                ..Default::default()
            }],
            push_constants: Some([0, 8]),
            robustness: Default::default(),
        }],
        ..Default::default()
    };
    let text = serde_yaml::to_string(&st).unwrap();
    assert_eq!(serde_yaml::from_str::<ResourceState>(&text).unwrap(), st);
    assert!(ResourceState::default().is_empty());
    let case = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../cases/hand/trace-indirect-basic.yaml"),
    )
    .unwrap();
    let case = model::Case::from_yaml("basic", &case).unwrap();
    assert!(case.as_trace().unwrap().world.resources.is_empty());
    assert!(
        !case.to_yaml().contains("resources"),
        "an empty resource state is not written"
    );
}

#[test]
fn compatibility_compares_set_layout_definitions_not_names() {
    let b = |t| LayoutBinding {
        binding: 0,
        ty: t,
        count: 1,
        immutable_samplers: vec![],
    };
    let st = ResourceState {
        set_layouts: vec![
            SetLayout {
                name: "a".into(),
                bindings: vec![b(DescriptorType::UniformBuffer)],
            },
            SetLayout {
                name: "a2".into(),
                bindings: vec![b(DescriptorType::UniformBuffer)],
            },
            SetLayout {
                name: "c".into(),
                bindings: vec![b(DescriptorType::StorageBuffer)],
            },
        ],
        pipeline_layouts: vec![
            PipelineLayout {
                name: "p".into(),
                sets: vec!["a".into(), "c".into()],
                push_ranges: vec![],
            },
            PipelineLayout {
                name: "q".into(),
                sets: vec!["a2".into(), "a".into()],
                push_ranges: vec![],
            },
        ],
        ..Default::default()
    };
    assert!(st.compatible_for_set("p", "q", 0));
    assert!(!st.compatible_for_set("p", "q", 1));
    assert!(st.compatible_for_push("p", "q"));
}

#[test]
fn view_types_match_dims_as_the_spirv_table_says() {
    assert!(view_type_matches(ViewType::CubeArray, Dim::Cube, true));
    assert!(!view_type_matches(ViewType::Cube, Dim::Cube, true));
    assert!(!view_type_matches(ViewType::TwoD, Dim::ThreeD, false));
    assert!(view_type_matches(ViewType::OneDArray, Dim::OneD, true));
}

#[test]
fn wording_variants_become_parameters() {
    use vk_registry::vuid::VuidSet;
    let set: VuidSet = vk_registry::source::load_vuids(std::path::Path::new(
        vk_registry::source::DEFAULT_REGISTRY_DIR,
    ))
    .unwrap();
    let rule = |id: &str| match rules::rule_for(set.records.iter().find(|r| r.id == id).unwrap()) {
        Some(Entry::Executable { rule, .. }) => rule,
        other => panic!("{id}: {other:?}"),
    };
    // 1.3.239 leaves the VK_EXT_filter_cubic exemption of 02693 to the registry condition; the
    // wording that states it in the text sets the parameter.
    let text = &set
        .records
        .iter()
        .find(|r| r.id == "VUID-vkCmdTraceRaysKHR-None-02693")
        .unwrap()
        .text;
    assert_eq!(
        rule("VUID-vkCmdTraceRaysKHR-None-02693"),
        ResourceRule::CubicViewType {
            unless_filter_cubic: text.contains("not enabled")
        }
    );
    assert_eq!(
        rule("VUID-vkCmdTraceRaysKHR-None-02699"),
        ResourceRule::DescriptorsValid {
            unless_descriptor_buffer: false
        }
    );
    assert!(matches!(
        rule("VUID-vkCmdTraceRaysNV-magFilter-04553"),
        ResourceRule::LinearFilterFeature { mipmap: false, .. }
    ));
}

#[test]
fn a_binding_s_immutable_sampler_is_the_one_an_access_uses() {
    let sampler = |name: &str, ycbcr| Sampler {
        name: name.into(),
        ycbcr_conversion: ycbcr,
        ..Default::default()
    };
    let mut st = ResourceState {
        set_layouts: vec![SetLayout {
            name: "sl".into(),
            bindings: vec![LayoutBinding {
                binding: 0,
                ty: DescriptorType::CombinedImageSampler,
                count: 1,
                immutable_samplers: vec!["immutable".into()],
            }],
        }],
        descriptor_sets: vec![DescriptorSet {
            name: "ds".into(),
            layout: "sl".into(),
            writes: vec![Write {
                binding: 0,
                element: 0,
                descriptor: Descriptor::Image {
                    view: "v".into(),
                    sampler: Some("written".into()),
                    layout: ImageLayout::ShaderReadOnlyOptimal,
                },
            }],
        }],
        bound_sets: vec![BoundSet {
            set: 0,
            descriptor_set: "ds".into(),
            layout: "pl".into(),
        }],
        samplers: vec![sampler("immutable", true), sampler("written", false)],
        stages: vec![StageUse {
            stage: Stage::Raygen,
            accesses: vec![Access {
                op: Op::Fetch,
                image: Some(ImageType::default()),
                ..Default::default()
            }],
            push_constants: None,
            robustness: Default::default(),
        }],
        ..Default::default()
    };
    let used = |st: &ResourceState| {
        rules::resolve(st)[0]
            .sampler
            .map(|s| s.name.clone())
            .unwrap_or_default()
    };
    assert_eq!(used(&st), "immutable");
    st.set_layouts[0].bindings[0].immutable_samplers.clear();
    assert_eq!(
        used(&st),
        "written",
        "without immutable samplers the write's is used"
    );
    // The state round-trips with the immutable sampler named in the YAML, and old states without one parse.
    st.set_layouts[0].bindings[0].immutable_samplers = vec!["immutable".into()];
    let text = serde_yaml::to_string(&st).unwrap();
    assert!(text.contains("immutable_samplers"), "{text}");
    assert_eq!(serde_yaml::from_str::<ResourceState>(&text).unwrap(), st);
    let old: LayoutBinding =
        serde_yaml::from_str("binding: 0\ntype: combined-image-sampler\n").unwrap();
    assert!(old.immutable_samplers.is_empty());
}
