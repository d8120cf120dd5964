//! The C `main` of a trace case: the device, the harness's descriptor layout, the pipeline (and the
//! foreign one) with its group handles, the world's buffers and their writes, the scene built from the
//! plan's bytes (bottom levels, instance records, top level), the harness's buffers and descriptor
//! set, then the plan's steps with the call under the layer, and a valid launch's records read back
//! and judged per launch ID against the model's tables (`crate::records`).

use crate::c::{self, Emitter};
use crate::{emit_device, emit_expectation, Expectation};
use harness::plan::pipeline::GroupType;
use harness::plan::scene::{GeometryDataPlan, AABB_STRIDE, VERTEX_STRIDE};
use harness::plan::trace::{BufferWrite, TraceCall, TracePlan};
use harness::plan::{Barrier, CallPlan, ShaderBody, ShaderKind, Step};
use model::flags::{BufferCreate, BufferUsage, PipelineCreate};
use model::tracer::record::RayRecord;
use model::world::{CommandBufferLevel, HandleRef, MemoryBinding, PipelineApi};

/// `main` for a trace plan, or what it cannot write.
pub(crate) fn emit(
    e: &mut Emitter,
    plan: &CallPlan,
    t: &TracePlan,
    expect: &Expectation,
) -> Result<(), String> {
    if t.api == PipelineApi::Nv || matches!(t.call, TraceCall::TraceRaysNv { .. }) {
        return Err("VK_NV_ray_tracing cases are not exported yet".into());
    }
    if t.resources {
        return Err(
            "resource states (descriptors, images, samplers, push constants) are not exported yet"
                .into(),
        );
    }
    if let Some(b) = t
        .buffers
        .iter()
        .find(|b| b.sparse || b.memory != MemoryBinding::Whole)
    {
        return Err(format!(
            "buffer `{}` is sparse or not bound whole; only wholly bound buffers are exported yet",
            b.name
        ));
    }
    let names: Vec<String> = t.buffers.iter().map(|b| b.name.clone()).collect();
    let addr = |a: &model::call::Address| {
        c::address(a, &names, "world")
            .ok_or_else(|| format!("the call names a buffer the world lacks: {a:?}"))
    };
    // The shaders the pipeline uses, their SPIR-V as data.
    let mut kinds: Vec<ShaderKind> = Vec::new();
    if let Some(p) = &t.pipeline {
        for s in &p.stages {
            if !kinds.contains(&s.shader) {
                kinds.push(s.shader);
            }
        }
    }
    let body = t.pipeline.as_ref().map_or(ShaderBody::Full, |p| p.body);
    e.line(&format!("/* The SPIR-V of the harness's shaders (harness/shaders/, glslangValidator --target-env vulkan1.2{}). */", match body {
        ShaderBody::Full => "",
        ShaderBody::InterfaceOnly => " -DINTERFACE_ONLY, its trace instructions removed: the case is recorded, never submitted",
    }));
    for k in &kinds {
        let words = harness::plan::spirv(*k, PipelineApi::Khr, body).map_err(|e| e.to_string())?;
        c::words(e, &format!("spirv_{}", k.output_name()), &words);
    }
    for (k, b) in t.buffers.iter().enumerate() {
        for (w, write) in b.writes.iter().enumerate() {
            if let BufferWrite::Bytes { bytes, .. } = write {
                c::bytes(e, &format!("bytes_{k}_{w}"), bytes);
            }
        }
    }
    c::le_words(e, "rays_bytes", &t.io.rays);
    c::bytes(e, "callables_bytes", &t.io.callables);
    if t.io.fill_output {
        e.line("/* The record every launch ID starts from (outcome NOT_RUN, group none, slots none). */");
        c::words(e, "record_prefill", &RayRecord::PREFILL);
    }
    match &t.scene {
        Some(s) => {
            c::le_words(e, "scene_input", &s.input);
            c::bytes(e, "instance_records", &s.instance_bytes(&|_| 0));
            c::words(e, "sphere_words", &s.spheres);
        }
        None => c::words(e, "sphere_words", &[0, 0, 0, 0]),
    }
    let launch = expect.launch.as_ref().filter(|_| read_back(t).is_some());
    if let Some(l) = launch {
        crate::records::tables(
            e,
            l.allowed.iter(),
            "distinct ray (model::semantics::expected_launch)",
        );
    }
    e.line("");
    e.open("int main(int argc, char **argv) {");
    e.line(
        "/* ./repro [--records FILE]: FILE receives the records read back (little-endian words).",
    );
    e.line(" * ./repro --judge FILE: judges the records in FILE against the model's tables, runs nothing. */");
    e.line("const char *records_path = argc > 2 && strcmp(argv[1], \"--records\") == 0 ? argv[2] : NULL;");
    e.line("(void)records_path;");
    if launch.is_some() {
        e.line("if (argc > 2 && strcmp(argv[1], \"--judge\") == 0)");
        e.line(&format!(
            "    return judge_file(&launch_rules, argv[2], {}ull);",
            t.io.records
        ));
    }
    emit_expectation(e, plan, expect);
    if launch.is_some() {
        e.line(&format!(
            "printf(\"         the launch's {} launch IDs are run for real, read back and judged per launch ID\\n\");",
            t.io.records
        ));
    }
    e.line(&format!("start({});", if plan.run_valid { 0 } else { 1 }));
    e.line("printf(\"calls:\\n\");");
    emit_device(e, &plan.device, false);
    e.line("VkPhysicalDeviceAccelerationStructurePropertiesKHR as_props = {VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_PROPERTIES_KHR};");
    e.line("VkPhysicalDeviceRayTracingPipelinePropertiesKHR rt_props = {VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_PROPERTIES_KHR};");
    e.line(
        "VkPhysicalDeviceProperties2 props2 = {VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};",
    );
    e.line("if (has_extension(\"VK_KHR_ray_tracing_pipeline\")) { rt_props.pNext = props2.pNext; props2.pNext = &rt_props; }");
    e.line("if (has_extension(\"VK_KHR_acceleration_structure\")) { as_props.pNext = props2.pNext; props2.pNext = &as_props; }");
    e.line("vkGetPhysicalDeviceProperties2(physical, &props2);");
    e.line("const uint32_t handle_size = rt_props.shaderGroupHandleSize;");
    e.line("(void)handle_size;");
    descriptor_layout(e, t);
    pipeline(e, t);
    world_buffers(e, t);
    if t.scene.is_some() {
        scene(e, t);
    }
    if t.in_render_pass {
        e.line("make_render_pass();");
        e.line("step(\"vkCreateRenderPass, vkCreateFramebuffer (empty, 1x1)\");");
    }
    io_and_set(e, t);
    let expected = launch.is_some();
    steps(e, t, expected, &addr)?;
    e.line("return differ || !output_ok ? 1 : 0;");
    e.close("}");
    Ok(())
}

/// The words a plan reads back, when it reads any.
fn read_back(t: &TracePlan) -> Option<usize> {
    t.steps.iter().find_map(|s| match s {
        Step::ReadBack { words } => Some(*words),
        _ => None,
    })
}

fn descriptor_layout(e: &mut Emitter, t: &TracePlan) {
    e.line(&format!(
        "VkDescriptorSetLayoutBinding bindings[{}];",
        t.bindings.len()
    ));
    e.line("memset(bindings, 0, sizeof bindings);");
    for (i, b) in t.bindings.iter().enumerate() {
        e.line(&format!(
            "bindings[{i}].binding = {}; bindings[{i}].descriptorType = (VkDescriptorType){}; bindings[{i}].descriptorCount = 1; bindings[{i}].stageFlags = 0x{:x};",
            b.binding, b.ty, b.stages
        ));
    }
    e.line("VkDescriptorSetLayoutCreateInfo set_info = {VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};");
    e.line(&format!("set_info.bindingCount = {};", t.bindings.len()));
    e.line("set_info.pBindings = bindings;");
    e.line("VkDescriptorSetLayout set_layout;");
    e.line("CHECK(vkCreateDescriptorSetLayout(device, &set_info, NULL, &set_layout));");
    e.line(
        "VkPipelineLayoutCreateInfo layout_info = {VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};",
    );
    e.line("layout_info.setLayoutCount = 1;");
    e.line("layout_info.pSetLayouts = &set_layout;");
    e.line("VkPipelineLayout pipeline_layout;");
    e.line("CHECK(vkCreatePipelineLayout(device, &layout_info, NULL, &pipeline_layout));");
    e.line("step(\"vkCreateDescriptorSetLayout (set 0: scene, records, rays, callables, spheres), vkCreatePipelineLayout\");");
}

fn pipeline(e: &mut Emitter, t: &TracePlan) {
    let Some(p) = &t.pipeline else {
        e.line("VkPipeline pipeline = VK_NULL_HANDLE;");
        e.line("uint32_t stack_size = 0;");
        e.line("(void)pipeline; (void)stack_size;");
        return;
    };
    let mut kinds: Vec<ShaderKind> = Vec::new();
    for s in &p.stages {
        if !kinds.contains(&s.shader) {
            kinds.push(s.shader);
        }
    }
    e.line(&format!("VkShaderModule modules[{}];", kinds.len().max(1)));
    for (i, k) in kinds.iter().enumerate() {
        let n = format!("spirv_{}", k.output_name());
        e.line(&format!(
            "{{ VkShaderModuleCreateInfo m = {{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO}}; m.codeSize = sizeof {n}; m.pCode = {n}; CHECK(vkCreateShaderModule(device, &m, NULL, &modules[{i}])); }}"
        ));
    }
    let s = p.stages.len().max(1);
    e.line(
        "/* One stage per shader a group uses, specialised by constant 0 to the group's index. */",
    );
    let constants: Vec<String> = p
        .stages
        .iter()
        .map(|x| format!("{{{}, {}}}", x.group, x.any_hit_rule))
        .collect();
    e.line(&format!(
        "static const uint32_t stage_constants[{s}][2] = {{{}}};",
        if constants.is_empty() {
            "{0, 0}".to_string()
        } else {
            constants.join(", ")
        }
    ));
    e.line("/* Constant 0: the group index; 1: the hit group's any-hit rule (only the any-hit shader declares it). */");
    e.line("VkSpecializationMapEntry entries[2] = {{0, 0, 4}, {1, 4, 4}};");
    e.line(&format!("VkSpecializationInfo spec[{s}];"));
    e.line(&format!("VkPipelineShaderStageCreateInfo stages[{s}];"));
    e.line("memset(stages, 0, sizeof stages);");
    for (i, st) in p.stages.iter().enumerate() {
        let m = kinds.iter().position(|k| *k == st.shader).unwrap_or(0);
        e.line(&format!(
            "spec[{i}].mapEntryCount = 2; spec[{i}].pMapEntries = entries; spec[{i}].dataSize = 8; spec[{i}].pData = stage_constants[{i}];"
        ));
        e.line(&format!(
            "stages[{i}].sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO; stages[{i}].stage = (VkShaderStageFlagBits)0x{:x}; stages[{i}].module = modules[{m}]; stages[{i}].pName = \"main\"; stages[{i}].pSpecializationInfo = &spec[{i}]; /* {} */",
            st.stage,
            st.shader.output_name()
        ));
    }
    let g = p.groups.len().max(1);
    e.line(&format!(
        "VkRayTracingShaderGroupCreateInfoKHR groups[{g}];"
    ));
    e.line("memset(groups, 0, sizeof groups);");
    for (i, gr) in p.groups.iter().enumerate() {
        let ty = match gr.ty {
            GroupType::General => "VK_RAY_TRACING_SHADER_GROUP_TYPE_GENERAL_KHR",
            GroupType::TrianglesHit => "VK_RAY_TRACING_SHADER_GROUP_TYPE_TRIANGLES_HIT_GROUP_KHR",
            GroupType::ProceduralHit => "VK_RAY_TRACING_SHADER_GROUP_TYPE_PROCEDURAL_HIT_GROUP_KHR",
        };
        let idx = |v: u32| {
            if v == harness::plan::pipeline::SHADER_UNUSED {
                "VK_SHADER_UNUSED_KHR".to_string()
            } else {
                v.to_string()
            }
        };
        e.line(&format!(
            "groups[{i}].sType = VK_STRUCTURE_TYPE_RAY_TRACING_SHADER_GROUP_CREATE_INFO_KHR; groups[{i}].type = {ty}; groups[{i}].generalShader = {}; groups[{i}].closestHitShader = {}; groups[{i}].anyHitShader = {}; groups[{i}].intersectionShader = {};",
            idx(gr.general),
            idx(gr.closest_hit),
            idx(gr.any_hit),
            idx(gr.intersection)
        ));
    }
    e.line("VkDynamicState dynamic_states[1] = {VK_DYNAMIC_STATE_RAY_TRACING_PIPELINE_STACK_SIZE_KHR};");
    e.line("VkPipelineDynamicStateCreateInfo dynamic = {VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO};");
    e.line("dynamic.dynamicStateCount = 1;");
    e.line("dynamic.pDynamicStates = dynamic_states;");
    e.line(&format!(
        "VkRayTracingPipelineInterfaceCreateInfoKHR interface_info = {{VK_STRUCTURE_TYPE_RAY_TRACING_PIPELINE_INTERFACE_CREATE_INFO_KHR, NULL, {}, {}}};",
        harness::plan::pipeline::MAX_PAYLOAD_SIZE,
        harness::plan::pipeline::MAX_HIT_ATTRIBUTE_SIZE
    ));
    e.line("VkRayTracingPipelineCreateInfoKHR pipeline_info = {VK_STRUCTURE_TYPE_RAY_TRACING_PIPELINE_CREATE_INFO_KHR};");
    e.line(&format!(
        "pipeline_info.flags = {};",
        c::flags(p.flags, PipelineCreate::NAMES)
    ));
    e.line(&format!("pipeline_info.stageCount = {};", p.stages.len()));
    e.line("pipeline_info.pStages = stages;");
    e.line(&format!("pipeline_info.groupCount = {};", p.groups.len()));
    e.line("pipeline_info.pGroups = groups;");
    e.line(&format!(
        "pipeline_info.maxPipelineRayRecursionDepth = {};",
        p.max_recursion_depth
    ));
    e.line("pipeline_info.layout = pipeline_layout;");
    if p.dynamic_stack_size {
        e.line("pipeline_info.pDynamicState = &dynamic;");
    }
    if p.library {
        e.line("pipeline_info.pLibraryInterface = &interface_info;");
    }
    e.line("(void)dynamic; (void)interface_info;");
    e.line("VkPipeline pipeline;");
    e.line("CHECK(pvkCreateRayTracingPipelinesKHR(device, VK_NULL_HANDLE, VK_NULL_HANDLE, 1, &pipeline_info, NULL, &pipeline));");
    e.line(&format!(
        "step(\"vkCreateRayTracingPipelinesKHR: {} stages, {} groups, maxPipelineRayRecursionDepth {}\");",
        p.stages.len(),
        p.groups.len(),
        p.max_recursion_depth
    ));
    let n = p.groups.len();
    e.line(&format!(
        "uint8_t *handles = calloc({}, handle_size ? handle_size : 1);",
        n.max(1)
    ));
    if !p.library && n > 0 {
        e.line(&format!(
            "CHECK(pvkGetRayTracingShaderGroupHandlesKHR(device, pipeline, 0, {n}, (size_t){n} * handle_size, handles));"
        ));
        e.line("step(\"vkGetRayTracingShaderGroupHandlesKHR\");");
    }
    if t.foreign_pipeline {
        e.line("/* A second, distinct pipeline of the same description: the source of foreign handles. */");
        e.line("VkPipeline foreign;");
        e.line("CHECK(pvkCreateRayTracingPipelinesKHR(device, VK_NULL_HANDLE, VK_NULL_HANDLE, 1, &pipeline_info, NULL, &foreign));");
        e.line(&format!(
            "uint8_t *foreign_handles = calloc({}, handle_size ? handle_size : 1);",
            n.max(1)
        ));
        if !p.library && n > 0 {
            e.line(&format!(
                "CHECK(pvkGetRayTracingShaderGroupHandlesKHR(device, foreign, 0, {n}, (size_t){n} * handle_size, foreign_handles));"
            ));
        }
        e.line("step(\"vkCreateRayTracingPipelinesKHR (a second pipeline), vkGetRayTracingShaderGroupHandlesKHR\");");
    }
    let stack = t.steps.contains(&Step::SetStackSize);
    if stack && !p.library {
        e.line(&format!(
            "uint32_t stack_size = default_stack_size(pipeline, groups, {n}, {});",
            p.max_recursion_depth
        ));
    } else {
        e.line("uint32_t stack_size = 0;");
    }
    e.line("(void)stack_size;");
}

fn world_buffers(e: &mut Emitter, t: &TracePlan) {
    e.line(&format!("struct buffer world[{}];", t.buffers.len().max(1)));
    e.line("uint8_t *zero_handle = calloc(1, handle_size ? handle_size : 1);");
    e.line("(void)zero_handle;");
    let groups = t.pipeline.as_ref().map_or(0, |p| p.groups.len() as u32);
    for (k, b) in t.buffers.iter().enumerate() {
        e.line(&format!(
            "world[{k}] = make_buffer({}ull, {}, {}, {}); /* `{}` */",
            b.size,
            c::flags(b.usage, BufferUsage::NAMES),
            c::flags(b.flags, BufferCreate::NAMES),
            model::call::BUFFER_PLACEMENT_ALIGNMENT,
            c::comment_safe(&b.name)
        ));
        e.line(&format!(
            "step({});",
            c::string(&format!("vkCreateBuffer `{}` ({} bytes)", b.name, b.size))
        ));
        for (w, write) in b.writes.iter().enumerate() {
            match write {
                BufferWrite::Bytes { offset, bytes } => e.line(&format!(
                    "write_bytes(&world[{k}], {offset}ull, bytes_{k}_{w}, {});",
                    bytes.len()
                )),
                BufferWrite::Handle { offset, handle } => {
                    let src = match handle {
                        HandleRef::Group(g) if *g < groups => {
                            format!("handles + (size_t){g} * handle_size")
                        }
                        HandleRef::Foreign(g) if *g < groups => {
                            format!("foreign_handles + (size_t){g} * handle_size")
                        }
                        // A group the pipeline lacks reads as zeros, as in the harness.
                        _ => "zero_handle".into(),
                    };
                    e.line(&format!(
                        "write_bytes(&world[{k}], {offset}ull, {src}, handle_size); /* {handle:?} */"
                    ));
                }
            }
        }
    }
}

/// The scene from the plan's bytes: the input buffer, every built bottom level's build recorded into
/// one command buffer, the instance records (the plan's, each patched with its bottom level's device
/// address), a barrier, the top level; submitted and waited for, as `realise::scene` does.
fn scene(e: &mut Emitter, t: &TracePlan) {
    let Some(s) = &t.scene else { return };
    e.line("/* The scene (harness::plan::scene): its input bytes, bottom levels and instance records. */");
    e.line("const VkBufferUsageFlags build_input = VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT;");
    e.line("const VkBufferUsageFlags storage_usage = VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_STORAGE_BIT_KHR | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT;");
    e.line("const VkBufferUsageFlags scratch_usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT;");
    e.line("VkDeviceSize scratch_align = as_props.minAccelerationStructureScratchOffsetAlignment > 256 ? as_props.minAccelerationStructureScratchOffsetAlignment : 256;");
    e.line("struct buffer input = make_buffer(sizeof scene_input, build_input, 0, 256);");
    e.line("write_bytes(&input, 0, scene_input, sizeof scene_input);");
    let b = s.bottoms.len().max(1);
    e.line(&format!("VkAccelerationStructureKHR bottoms[{b}];"));
    e.line(&format!("VkDeviceAddress bottom_addresses[{b}];"));
    e.line("memset(bottoms, 0, sizeof bottoms);");
    e.line("memset(bottom_addresses, 0, sizeof bottom_addresses);");
    e.line("begin_one_time(primary);");
    for (i, bl) in s.bottoms.iter().enumerate() {
        if !bl.built() {
            e.line(&format!(
                "/* bottom level {i}: no geometries, not built (instances reference 0) */"
            ));
            continue;
        }
        let n = bl.geometries.len();
        e.open("{");
        e.line(&format!("VkAccelerationStructureGeometryKHR g[{n}];"));
        e.line(&format!("VkAccelerationStructureBuildRangeInfoKHR r[{n}];"));
        e.line("memset(g, 0, sizeof g);");
        e.line("memset(r, 0, sizeof r);");
        let counts: Vec<String> = bl
            .geometries
            .iter()
            .map(|g| g.primitive_count.to_string())
            .collect();
        e.line(&format!(
            "uint32_t counts[{n}] = {{{}}};",
            counts.join(", ")
        ));
        for (j, g) in bl.geometries.iter().enumerate() {
            e.line(&format!(
                "g[{j}].sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR; g[{j}].flags = {};",
                c::flags(g.flags, &[("VK_GEOMETRY_OPAQUE_BIT_KHR", 1), ("VK_GEOMETRY_NO_DUPLICATE_ANY_HIT_INVOCATION_BIT_KHR", 2)])
            ));
            match g.data {
                GeometryDataPlan::Triangles {
                    vertices,
                    vertex_count,
                    indices,
                    transform,
                } => {
                    e.line(&format!(
                        "g[{j}].geometryType = VK_GEOMETRY_TYPE_TRIANGLES_KHR;"
                    ));
                    e.line(&format!("g[{j}].geometry.triangles.sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_TRIANGLES_DATA_KHR;"));
                    e.line(&format!(
                        "g[{j}].geometry.triangles.vertexFormat = VK_FORMAT_R32G32B32_SFLOAT;"
                    ));
                    e.line(&format!(
                        "g[{j}].geometry.triangles.vertexData.deviceAddress = input.address + {vertices}; g[{j}].geometry.triangles.vertexStride = {VERTEX_STRIDE}; g[{j}].geometry.triangles.maxVertex = {};",
                        vertex_count.saturating_sub(1)
                    ));
                    match indices {
                        Some((o, _, bits)) => e.line(&format!(
                            "g[{j}].geometry.triangles.indexType = VK_INDEX_TYPE_UINT{bits}; g[{j}].geometry.triangles.indexData.deviceAddress = input.address + {o};"
                        )),
                        None => e.line(&format!(
                            "g[{j}].geometry.triangles.indexType = VK_INDEX_TYPE_NONE_KHR;"
                        )),
                    }
                    if let Some(o) = transform {
                        e.line(&format!(
                            "g[{j}].geometry.triangles.transformData.deviceAddress = input.address + {o}; /* row-major 3x4 */"
                        ));
                    }
                }
                GeometryDataPlan::Aabbs { boxes, .. } => {
                    e.line(&format!(
                        "g[{j}].geometryType = VK_GEOMETRY_TYPE_AABBS_KHR;"
                    ));
                    e.line(&format!("g[{j}].geometry.aabbs.sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_AABBS_DATA_KHR;"));
                    e.line(&format!(
                        "g[{j}].geometry.aabbs.data.deviceAddress = input.address + {boxes}; g[{j}].geometry.aabbs.stride = {AABB_STRIDE};"
                    ));
                }
            }
            e.line(&format!("r[{j}].primitiveCount = counts[{j}];"));
        }
        e.line("VkDeviceAddress scratch;");
        sized_structure(
            e,
            "VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR",
            n,
            "g",
            &format!("bottoms[{i}]"),
            "scratch",
        );
        e.line(&format!("VkAccelerationStructureDeviceAddressInfoKHR a = {{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_DEVICE_ADDRESS_INFO_KHR, NULL, bottoms[{i}]}};"));
        e.line(&format!(
            "bottom_addresses[{i}] = pvkGetAccelerationStructureDeviceAddressKHR(device, &a);"
        ));
        e.line("VkAccelerationStructureBuildGeometryInfoKHR info = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};");
        e.line("info.type = VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR;");
        e.line("info.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;");
        e.line(&format!("info.geometryCount = {n};"));
        e.line("info.pGeometries = g;");
        e.line(&format!("info.dstAccelerationStructure = bottoms[{i}];"));
        e.line("info.scratchData.deviceAddress = scratch;");
        e.line("const VkAccelerationStructureBuildRangeInfoKHR *ranges = r;");
        e.line("pvkCmdBuildAccelerationStructuresKHR(primary, 1, &info, &ranges);");
        e.line(&format!(
            "step(\"vkCmdBuildAccelerationStructuresKHR: bottom level {i} ({n} geometries)\");"
        ));
        e.close("}");
    }
    let n = s.instances.len();
    let bottoms: Vec<String> = s
        .instances
        .iter()
        .map(|i| i.bottom.map_or("-1".to_string(), |b| b.to_string()))
        .collect();
    e.line("/* The instance records with reference 0; each active one gets its bottom level's address. */");
    e.line(&format!(
        "static const int instance_bottom[{}] = {{{}}};",
        n.max(1),
        if bottoms.is_empty() {
            "-1".to_string()
        } else {
            bottoms.join(", ")
        }
    ));
    e.line("uint8_t records[sizeof instance_records];");
    e.line("memcpy(records, instance_records, sizeof records);");
    if n > 0 {
        e.line(&format!(
            "for (int i = 0; i < {n}; i++) if (instance_bottom[i] >= 0) memcpy(records + 64 * i + 56, &bottom_addresses[instance_bottom[i]], 8);"
        ));
    } else {
        e.line("(void)instance_bottom;");
    }
    e.line("struct buffer instances = make_buffer(sizeof records, build_input, 0, 256);");
    e.line("write_bytes(&instances, 0, records, sizeof records);");
    e.line("memory_barrier(primary, VK_PIPELINE_STAGE_ACCELERATION_STRUCTURE_BUILD_BIT_KHR, VK_ACCESS_ACCELERATION_STRUCTURE_WRITE_BIT_KHR,");
    e.line("               VK_PIPELINE_STAGE_ACCELERATION_STRUCTURE_BUILD_BIT_KHR | VK_PIPELINE_STAGE_RAY_TRACING_SHADER_BIT_KHR, VK_ACCESS_ACCELERATION_STRUCTURE_READ_BIT_KHR);");
    e.line("VkAccelerationStructureGeometryKHR top_geometry = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};");
    e.line("top_geometry.geometryType = VK_GEOMETRY_TYPE_INSTANCES_KHR;");
    e.line("top_geometry.geometry.instances.sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_INSTANCES_DATA_KHR;");
    e.line("top_geometry.geometry.instances.data.deviceAddress = instances.address;");
    e.line("VkAccelerationStructureKHR top;");
    e.open("{");
    e.line(&format!("uint32_t counts[1] = {{{n}}};"));
    e.line("VkDeviceAddress scratch;");
    sized_structure(
        e,
        "VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR",
        1,
        "(&top_geometry)",
        "top",
        "scratch",
    );
    e.line("VkAccelerationStructureBuildGeometryInfoKHR info = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};");
    e.line("info.type = VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR;");
    e.line("info.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;");
    e.line("info.geometryCount = 1;");
    e.line("info.pGeometries = &top_geometry;");
    e.line("info.dstAccelerationStructure = top;");
    e.line("info.scratchData.deviceAddress = scratch;");
    e.line(&format!(
        "VkAccelerationStructureBuildRangeInfoKHR range = {{{n}, 0, 0, 0}};"
    ));
    e.line("const VkAccelerationStructureBuildRangeInfoKHR *ranges = &range;");
    e.line("pvkCmdBuildAccelerationStructuresKHR(primary, 1, &info, &ranges);");
    e.close("}");
    e.line("CHECK(vkEndCommandBuffer(primary));");
    e.line("submit_and_wait(primary);");
    e.line(&format!(
        "step(\"vkCmdBuildAccelerationStructuresKHR: top level of {n} instance(s); submitted and waited for\");"
    ));
}

/// Sizes, creates and gives scratch to a structure of `ty` over `count` geometries at `geoms`, with the
/// primitive counts in `counts`: storage at a 256-aligned address, scratch at `scratch_align`.
fn sized_structure(e: &mut Emitter, ty: &str, count: usize, geoms: &str, out: &str, scratch: &str) {
    e.line("VkAccelerationStructureBuildGeometryInfoKHR q = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};");
    e.line(&format!("q.type = {ty};"));
    e.line("q.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;");
    e.line(&format!("q.geometryCount = {count};"));
    e.line(&format!("q.pGeometries = {geoms};"));
    e.line("VkAccelerationStructureBuildSizesInfoKHR sizes = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_SIZES_INFO_KHR};");
    e.line("pvkGetAccelerationStructureBuildSizesKHR(device, VK_ACCELERATION_STRUCTURE_BUILD_TYPE_DEVICE_KHR, &q, counts, &sizes);");
    e.line("struct buffer storage = make_buffer(sizes.accelerationStructureSize, storage_usage, 0, 256);");
    e.line("struct buffer scratch_buffer = make_buffer(sizes.buildScratchSize ? sizes.buildScratchSize : 1, scratch_usage, 0, scratch_align);");
    e.line("VkAccelerationStructureCreateInfoKHR c = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_CREATE_INFO_KHR};");
    e.line("c.buffer = storage.buffer;");
    e.line("c.size = sizes.accelerationStructureSize;");
    e.line(&format!("c.type = {ty};"));
    e.line(&format!(
        "CHECK(pvkCreateAccelerationStructureKHR(device, &c, NULL, &{out}));"
    ));
    e.line(&format!("{scratch} = scratch_buffer.address;"));
}

fn io_and_set(e: &mut Emitter, t: &TracePlan) {
    let rays = t.io.rays.len().saturating_sub(16) / harness::plan::trace::RAY_RECORD_SIZE;
    let calls = t.io.callables.len().saturating_sub(16) / 4;
    let out_size = t.io.output_words * 4;
    let rays_size = (16 + rays.max(1) * harness::plan::trace::RAY_RECORD_SIZE).max(4096);
    let calls_size = (16 + calls.max(1) * 4).max(256);
    e.line("/* The harness's buffers: the ray records, rays, callable record indices, spheres. */");
    e.line(&format!(
        "struct buffer output = make_buffer({out_size}, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, 0, 1);"
    ));
    e.line(&format!(
        "struct buffer rays = make_buffer({rays_size}, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, 0, 1);"
    ));
    e.line(&format!(
        "struct buffer callables = make_buffer({calls_size}, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, 0, 1);"
    ));
    e.line("struct buffer spheres = make_buffer(sizeof sphere_words, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, 0, 1);");
    e.line("write_bytes(&spheres, 0, sphere_words, sizeof sphere_words);");
    if t.io.fill_output {
        e.line(&format!(
            "for (uint64_t i = 0; i < {}ull; i++) write_bytes(&output, i * RECORD_WORDS * 4, record_prefill, sizeof record_prefill);",
            t.io.records
        ));
    }
    e.line("write_bytes(&rays, 0, rays_bytes, sizeof rays_bytes);");
    e.line("write_bytes(&callables, 0, callables_bytes, sizeof callables_bytes);");
    e.line("VkDescriptorPoolSize pool_sizes[2] = {{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 8}, {VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR, 2}};");
    e.line(&format!(
        "VkDescriptorSet set = one_set(set_layout, pool_sizes, {}, 2);",
        if t.scene.is_some() { 2 } else { 1 }
    ));
    e.line("/* Binding 1 covers exactly the launch's records: the any-hit and intersection shaders bound their writes by its length. */");
    e.line(&format!(
        "VkDescriptorBufferInfo infos[4] = {{{{output.buffer, 0, {out_size}}}, {{rays.buffer, 0, VK_WHOLE_SIZE}}, {{callables.buffer, 0, VK_WHOLE_SIZE}}, {{spheres.buffer, 0, VK_WHOLE_SIZE}}}};"
    ));
    e.line("VkWriteDescriptorSet writes[5];");
    e.line("memset(writes, 0, sizeof writes);");
    e.open("for (int i = 0; i < 4; i++) {");
    e.line("writes[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;");
    e.line("writes[i].dstSet = set;");
    e.line("writes[i].dstBinding = (uint32_t)i + 1;");
    e.line("writes[i].descriptorCount = 1;");
    e.line("writes[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;");
    e.line("writes[i].pBufferInfo = &infos[i];");
    e.close("}");
    if t.scene.is_some() {
        e.line("VkWriteDescriptorSetAccelerationStructureKHR structure_write = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET_ACCELERATION_STRUCTURE_KHR, NULL, 1, &top};");
        e.line("writes[4].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;");
        e.line("writes[4].pNext = &structure_write;");
        e.line("writes[4].dstSet = set;");
        e.line("writes[4].dstBinding = 0;");
        e.line("writes[4].descriptorCount = 1;");
        e.line("writes[4].descriptorType = VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR;");
        e.line("vkUpdateDescriptorSets(device, 5, writes, 0, NULL);");
    } else {
        e.line("vkUpdateDescriptorSets(device, 4, writes, 0, NULL);");
    }
    e.line("step(\"vkCreateBuffer records, rays, callables, spheres; vkAllocateDescriptorSets, vkUpdateDescriptorSets\");");
}

fn steps(
    e: &mut Emitter,
    t: &TracePlan,
    expected: bool,
    addr: &dyn Fn(&model::call::Address) -> Result<String, String>,
) -> Result<(), String> {
    let cb = match t.level {
        CommandBufferLevel::Primary => "primary",
        CommandBufferLevel::Secondary => "secondary",
    };
    e.line(&format!("VkCommandBuffer cb = {cb};"));
    e.line("int differ = 0;");
    e.line("int output_ok = 1;");
    for s in &t.steps {
        e.line(&format!(
            "step({});",
            c::string(&harness::plan::step_text(s))
        ));
        match s {
            Step::Begin { level, .. } => {
                e.open("{");
                e.line("VkCommandBufferInheritanceInfo inherit = {VK_STRUCTURE_TYPE_COMMAND_BUFFER_INHERITANCE_INFO};");
                e.line("VkCommandBufferBeginInfo begin = {VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};");
                e.line("begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;");
                if *level == CommandBufferLevel::Secondary {
                    e.line("begin.pInheritanceInfo = &inherit;");
                }
                e.line("(void)inherit;");
                e.line("CHECK(vkBeginCommandBuffer(cb, &begin));");
                e.close("}");
            }
            Step::Barrier(Barrier::SceneBuildToShaders) => e.line("memory_barrier(cb, VK_PIPELINE_STAGE_ACCELERATION_STRUCTURE_BUILD_BIT_KHR, VK_ACCESS_ACCELERATION_STRUCTURE_WRITE_BIT_KHR, VK_PIPELINE_STAGE_RAY_TRACING_SHADER_BIT_KHR, VK_ACCESS_ACCELERATION_STRUCTURE_READ_BIT_KHR);"),
            Step::Barrier(Barrier::ShaderWritesToHost) => e.line("memory_barrier(cb, VK_PIPELINE_STAGE_RAY_TRACING_SHADER_BIT_KHR, VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_HOST_READ_BIT);"),
            Step::BindPipeline => {
                if t.pipeline.is_some() {
                    e.line("vkCmdBindPipeline(cb, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, pipeline);");
                }
            }
            Step::SetStackSize => e.line("pvkCmdSetRayTracingPipelineStackSizeKHR(cb, stack_size ? stack_size : 4096);"),
            Step::BindHarnessSet => e.line("vkCmdBindDescriptorSets(cb, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, pipeline_layout, 0, 1, &set, 0, NULL);"),
            Step::BeginRenderPass => e.line("begin_render_pass(cb, VK_SUBPASS_CONTENTS_INLINE);"),
            Step::EndRenderPass => e.line("vkCmdEndRenderPass(cb);"),
            Step::End => e.line("CHECK(vkEndCommandBuffer(cb));"),
            Step::Call { dropped } => call(e, t, *dropped, addr)?,
            Step::Submit => {
                e.line("CHECK(vkEndCommandBuffer(cb));");
                e.line("submit_and_wait(cb);");
            }
            Step::ReadBack { .. } if !expected => {
                e.line("printf(\"output:  read back; the model states no records for this launch\\n\");");
            }
            Step::ReadBack { words } => {
                e.open("{");
                e.line("const uint32_t *got = read_words(&output);");
                e.line(&format!("if (records_path) save_records(records_path, got, {words}ull);"));
                e.line(&format!(
                    "uint64_t failed = judge_records(&launch_rules, got, {}ull);",
                    words / RayRecord::WORDS
                ));
                e.line("output_ok = failed == 0;");
                e.line("if (output_ok)");
                e.line(&format!(
                    "    printf(\"output:  matches the model ({} launch IDs)\\n\");",
                    words / RayRecord::WORDS
                ));
                e.line("else");
                e.line("    printf(\"output:  DIFFERS from the model at %llu launch ID(s)\\n\", (unsigned long long)failed);");
                e.close("}");
            }
            Step::ResourceTransitions | Step::ResourceBinds => {
                return Err("resource states are not exported yet".into())
            }
            Step::Reset { .. } | Step::SubmitToInvalidate => {}
        }
    }
    e.line("printf(\"verdict: %s\\n\", differ || !output_ok ? \"the driver or the layer departs from the model\" : \"the driver and the layer do what the model expects\");");
    Ok(())
}

fn call(
    e: &mut Emitter,
    t: &TracePlan,
    dropped: bool,
    addr: &dyn Fn(&model::call::Address) -> Result<String, String>,
) -> Result<(), String> {
    let region = |r: &model::call::StridedRegion| -> Result<String, String> {
        Ok(format!(
            "{{{}, {}ull, {}ull}}",
            addr(&r.address)?,
            r.stride,
            r.size
        ))
    };
    match &t.call {
        TraceCall::TraceRays { regions, .. } | TraceCall::TraceRaysIndirect { regions, .. } => {
            e.line("VkStridedDeviceAddressRegionKHR regions[4] = {");
            for r in regions {
                e.line(&format!("    {},", region(r)?));
            }
            e.line("};");
        }
        TraceCall::TraceRaysNv { .. } => return Err("vkCmdTraceRaysNV is not exported yet".into()),
    }
    e.line("clear_messages();");
    e.line(&format!(
        "drop_calls = {}; /* {} */",
        dropped as u8,
        if dropped {
            "the messenger returns VK_TRUE: the layer drops the invalid call"
        } else {
            "the valid call reaches the driver"
        }
    ));
    match &t.call {
        TraceCall::TraceRays { dims, .. } => e.line(&format!(
            "pvkCmdTraceRaysKHR(cb, &regions[0], &regions[1], &regions[2], &regions[3], {}, {}, {});",
            dims[0], dims[1], dims[2]
        )),
        TraceCall::TraceRaysIndirect { indirect, .. } => e.line(&format!(
            "pvkCmdTraceRaysIndirectKHR(cb, &regions[0], &regions[1], &regions[2], &regions[3], {});",
            addr(indirect)?
        )),
        TraceCall::TraceRaysNv { .. } => {}
    }
    e.line("drop_calls = 0;");
    e.line("printf(\"layer's messages:\\n\");");
    e.line("differ = report_layer(model_vuids, model_vuid_count);");
    e.line("clear_messages();");
    Ok(())
}
