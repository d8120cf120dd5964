//! The C `main` of a trace case: the device, the harness's descriptor layout, the pipeline (and the
//! foreign one) with its group handles, the world's buffers and their writes, the scene, the
//! harness's buffers and descriptor set, then the plan's steps with the call under the layer, and a
//! valid launch's output compared with the model's words.

use crate::c::{self, Emitter};
use crate::{emit_device, emit_expectation, Expectation};
use harness::plan::pipeline::GroupType;
use harness::plan::scene::{AABB_STRIDE, TRIANGLE_VERTICES, VERTEX_STRIDE};
use harness::plan::trace::{BufferWrite, TraceCall, TracePlan};
use harness::plan::{Barrier, CallPlan, ShaderKind, Step};
use model::flags::{BufferCreate, BufferUsage, PipelineCreate};
use model::world::{CommandBufferLevel, GeometryKind, HandleRef, MemoryBinding, PipelineApi};

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
    e.line("/* The SPIR-V of the harness's shaders (harness/shaders/, glslangValidator --target-env vulkan1.2). */");
    for k in &kinds {
        let words = harness::plan::spirv(*k, PipelineApi::Khr).map_err(|e| e.to_string())?;
        c::words(e, &format!("spirv_{}", k.output_name()), &words);
    }
    for (k, b) in t.buffers.iter().enumerate() {
        for (w, write) in b.writes.iter().enumerate() {
            if let BufferWrite::Bytes { bytes, .. } = write {
                c::bytes(e, &format!("bytes_{k}_{w}"), bytes);
            }
        }
    }
    c::bytes(e, "rays_bytes", &t.io.rays);
    c::bytes(e, "callables_bytes", &t.io.callables);
    if let Some(s) = &t.scene {
        c::bytes(e, "scene_input", &s.input);
    }
    if let Some(words) = expect
        .expected_words
        .as_ref()
        .filter(|_| read_back(t).is_some())
    {
        // Runs of equal words: a launch repeats its rays' words.
        let mut runs: Vec<(u32, u32)> = Vec::new();
        for w in words {
            match runs.last_mut() {
                Some((v, n)) if v == w && *n < u32::MAX => *n += 1,
                _ => runs.push((*w, 1)),
            }
        }
        e.line(&format!(
            "/* The {} words the model expects the launch to write, as (word, repeats). */",
            words.len()
        ));
        e.line(&format!(
            "static const uint32_t expected_runs[{}][2] = {{",
            runs.len().max(1)
        ));
        if runs.is_empty() {
            e.line("    {0, 0},");
        }
        for chunk in runs.chunks(4) {
            let row: Vec<String> = chunk
                .iter()
                .map(|(v, n)| format!("{{0x{v:08x}, {n}}}"))
                .collect();
            e.line(&format!("    {},", row.join(", ")));
        }
        e.line("};");
        e.line(&format!(
            "static const uint64_t expected_words = {};",
            words.len()
        ));
    }
    e.line("");
    e.open("int main(void) {");
    emit_expectation(e, plan, expect);
    if let Some(words) = expect
        .expected_words
        .as_ref()
        .filter(|_| read_back(t).is_some())
    {
        e.line(&format!(
            "printf(\"         the launch writes {} words, run for real and read back\\n\");",
            words.len()
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
    let expected = expect.expected_words.is_some() && read_back(t).is_some();
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
    e.line("step(\"vkCreateDescriptorSetLayout (set 0: scene, output, rays, callables), vkCreatePipelineLayout\");");
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
    let groups_of_stages: Vec<String> = p.stages.iter().map(|x| x.group.to_string()).collect();
    e.line(&format!(
        "static const uint32_t stage_group[{s}] = {{{}}};",
        if groups_of_stages.is_empty() {
            "0".to_string()
        } else {
            groups_of_stages.join(", ")
        }
    ));
    e.line("VkSpecializationMapEntry entry = {0, 0, 4};");
    e.line(&format!("VkSpecializationInfo spec[{s}];"));
    e.line(&format!("VkPipelineShaderStageCreateInfo stages[{s}];"));
    e.line("memset(stages, 0, sizeof stages);");
    for (i, st) in p.stages.iter().enumerate() {
        let m = kinds.iter().position(|k| *k == st.shader).unwrap_or(0);
        e.line(&format!(
            "spec[{i}].mapEntryCount = 1; spec[{i}].pMapEntries = &entry; spec[{i}].dataSize = 4; spec[{i}].pData = &stage_group[{i}];"
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

fn scene(e: &mut Emitter, t: &TracePlan) {
    let Some(s) = &t.scene else { return };
    e.line("/* The scene: one bottom-level structure per instance with geometry, a top-level one over them. */");
    e.line("const VkBufferUsageFlags build_input = VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT;");
    e.line("const VkBufferUsageFlags storage_usage = VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_STORAGE_BIT_KHR | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT;");
    e.line("const VkBufferUsageFlags scratch_usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT;");
    e.line("VkDeviceSize scratch_align = as_props.minAccelerationStructureScratchOffsetAlignment > 256 ? as_props.minAccelerationStructureScratchOffsetAlignment : 256;");
    e.line(&format!(
        "struct buffer input = make_buffer({}, build_input, 0, 256);",
        s.input.len().max(16)
    ));
    e.line(&format!(
        "write_bytes(&input, 0, scene_input, {});",
        s.input.len()
    ));
    let b = s.bottoms.len().max(1);
    e.line(&format!("VkAccelerationStructureKHR bottoms[{b}];"));
    e.line(&format!("VkDeviceAddress bottom_addresses[{b}];"));
    e.line(&format!("VkDeviceAddress bottom_scratch[{b}];"));
    e.line(&format!(
        "VkAccelerationStructureGeometryKHR *bottom_geometries[{b}];"
    ));
    e.line(&format!(
        "VkAccelerationStructureBuildRangeInfoKHR *bottom_ranges[{b}];"
    ));
    e.line("(void)bottoms; (void)bottom_addresses; (void)bottom_scratch; (void)bottom_geometries; (void)bottom_ranges;");
    for (i, geoms) in s.bottoms.iter().enumerate() {
        e.open("{");
        e.line(&format!(
            "VkAccelerationStructureGeometryKHR *g = calloc({}, sizeof *g);",
            geoms.len()
        ));
        e.line(&format!(
            "VkAccelerationStructureBuildRangeInfoKHR *r = calloc({}, sizeof *r);",
            geoms.len()
        ));
        e.line(&format!("uint32_t counts[{}];", geoms.len()));
        for (j, g) in geoms.iter().enumerate() {
            e.line(&format!(
                "g[{j}].sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR;"
            ));
            match g.kind {
                GeometryKind::Triangles => {
                    e.line(&format!(
                        "g[{j}].geometryType = VK_GEOMETRY_TYPE_TRIANGLES_KHR;"
                    ));
                    e.line(&format!("g[{j}].geometry.triangles.sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_TRIANGLES_DATA_KHR;"));
                    e.line(&format!(
                        "g[{j}].geometry.triangles.vertexFormat = VK_FORMAT_R32G32B32_SFLOAT;"
                    ));
                    e.line(&format!(
                        "g[{j}].geometry.triangles.vertexData.deviceAddress = input.address + {};",
                        g.offset
                    ));
                    e.line(&format!(
                        "g[{j}].geometry.triangles.vertexStride = {VERTEX_STRIDE};"
                    ));
                    e.line(&format!(
                        "g[{j}].geometry.triangles.maxVertex = {};",
                        TRIANGLE_VERTICES - 1
                    ));
                    e.line(&format!(
                        "g[{j}].geometry.triangles.indexType = VK_INDEX_TYPE_NONE_KHR;"
                    ));
                }
                GeometryKind::Aabbs => {
                    e.line(&format!(
                        "g[{j}].geometryType = VK_GEOMETRY_TYPE_AABBS_KHR;"
                    ));
                    e.line(&format!("g[{j}].geometry.aabbs.sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_AABBS_DATA_KHR;"));
                    e.line(&format!(
                        "g[{j}].geometry.aabbs.data.deviceAddress = input.address + {};",
                        g.offset
                    ));
                    e.line(&format!("g[{j}].geometry.aabbs.stride = {AABB_STRIDE};"));
                }
            }
            e.line(&format!("r[{j}].primitiveCount = 1; counts[{j}] = 1;"));
        }
        e.line(&format!(
            "bottoms[{i}] = VK_NULL_HANDLE; bottom_geometries[{i}] = g; bottom_ranges[{i}] = r;"
        ));
        sized_structure(
            e,
            "VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR",
            geoms.len(),
            "g",
            &format!("bottoms[{i}]"),
            &format!("bottom_scratch[{i}]"),
        );
        e.line(&format!(
            "VkAccelerationStructureDeviceAddressInfoKHR a = {{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_DEVICE_ADDRESS_INFO_KHR, NULL, bottoms[{i}]}};"
        ));
        e.line(&format!(
            "bottom_addresses[{i}] = pvkGetAccelerationStructureDeviceAddressKHR(device, &a);"
        ));
        e.close("}");
    }
    let n = s.instances.len();
    e.line(&format!("uint8_t records[{}];", (64 * n).max(64)));
    e.line("memset(records, 0, sizeof records);");
    for (i, inst) in s.instances.iter().enumerate() {
        let reference = match inst.bottom {
            Some(k) => format!("bottom_addresses[{k}]"),
            None => "0 /* no geometry: an inactive instance */".into(),
        };
        e.line(&format!(
            "instance_record(records + {}, 0x{:02x}, {}, {reference});",
            64 * i,
            inst.mask,
            inst.sbt_record_offset
        ));
    }
    e.line("struct buffer instances = make_buffer(sizeof records, build_input, 0, 256);");
    e.line("write_bytes(&instances, 0, records, sizeof records);");
    e.line("VkAccelerationStructureGeometryKHR top_geometry = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};");
    e.line("top_geometry.geometryType = VK_GEOMETRY_TYPE_INSTANCES_KHR;");
    e.line("top_geometry.geometry.instances.sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_INSTANCES_DATA_KHR;");
    e.line("top_geometry.geometry.instances.data.deviceAddress = instances.address;");
    e.line("VkAccelerationStructureKHR top;");
    e.line("VkDeviceAddress top_scratch;");
    e.open("{");
    e.line(&format!("uint32_t counts[1] = {{{n}}};"));
    sized_structure(
        e,
        "VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR",
        1,
        "(&top_geometry)",
        "top",
        "top_scratch",
    );
    e.close("}");
    e.line("begin_one_time(primary);");
    for i in 0..s.bottoms.len() {
        let g = s.bottoms[i].len();
        e.open("{");
        e.line("VkAccelerationStructureBuildGeometryInfoKHR b = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};");
        e.line("b.type = VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR;");
        e.line("b.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;");
        e.line(&format!("b.geometryCount = {g};"));
        e.line(&format!("b.pGeometries = bottom_geometries[{i}];"));
        e.line(&format!("b.dstAccelerationStructure = bottoms[{i}];"));
        e.line(&format!(
            "b.scratchData.deviceAddress = bottom_scratch[{i}];"
        ));
        e.line(&format!(
            "const VkAccelerationStructureBuildRangeInfoKHR *r = bottom_ranges[{i}];"
        ));
        e.line("pvkCmdBuildAccelerationStructuresKHR(primary, 1, &b, &r);");
        e.close("}");
    }
    e.line("memory_barrier(primary, VK_PIPELINE_STAGE_ACCELERATION_STRUCTURE_BUILD_BIT_KHR, VK_ACCESS_ACCELERATION_STRUCTURE_WRITE_BIT_KHR,");
    e.line("               VK_PIPELINE_STAGE_ACCELERATION_STRUCTURE_BUILD_BIT_KHR | VK_PIPELINE_STAGE_RAY_TRACING_SHADER_BIT_KHR, VK_ACCESS_ACCELERATION_STRUCTURE_READ_BIT_KHR);");
    e.open("{");
    e.line("VkAccelerationStructureBuildGeometryInfoKHR b = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};");
    e.line("b.type = VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR;");
    e.line("b.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;");
    e.line("b.geometryCount = 1;");
    e.line("b.pGeometries = &top_geometry;");
    e.line("b.dstAccelerationStructure = top;");
    e.line("b.scratchData.deviceAddress = top_scratch;");
    e.line(&format!(
        "VkAccelerationStructureBuildRangeInfoKHR range = {{{n}, 0, 0, 0}};"
    ));
    e.line("const VkAccelerationStructureBuildRangeInfoKHR *r = &range;");
    e.line("pvkCmdBuildAccelerationStructuresKHR(primary, 1, &b, &r);");
    e.close("}");
    e.line("CHECK(vkEndCommandBuffer(primary));");
    e.line("submit_and_wait(primary);");
    e.line(&format!(
        "step(\"built the scene: {} bottom-level structure(s), a top-level one of {n} instance(s)\");",
        s.bottoms.len()
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
    let out_size = (t.io.output_words.max(1) * 4).max(4096);
    let rays_size = (16 + rays.max(1) * harness::plan::trace::RAY_RECORD_SIZE).max(4096);
    let calls_size = (16 + calls.max(1) * 4).max(256);
    e.line("/* The harness's buffers: output words, rays, callable record indices. */");
    e.line(&format!(
        "struct buffer output = make_buffer({out_size}, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, 0, 1);"
    ));
    e.line(&format!(
        "struct buffer rays = make_buffer({rays_size}, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, 0, 1);"
    ));
    e.line(&format!(
        "struct buffer callables = make_buffer({calls_size}, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, 0, 1);"
    ));
    if t.io.fill_output {
        e.line(&format!(
            "for (uint64_t i = 0; i < {}; i++) {{ uint32_t not_run = 0x{:08x}u; write_bytes(&output, i * 4, &not_run, 4); }}",
            t.io.output_words,
            model::tracer::record::RayRecord::NOT_RUN
        ));
    }
    e.line("write_bytes(&rays, 0, rays_bytes, sizeof rays_bytes);");
    e.line("write_bytes(&callables, 0, callables_bytes, sizeof callables_bytes);");
    e.line("VkDescriptorPoolSize pool_sizes[2] = {{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 6}, {VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR, 2}};");
    e.line(
        "VkDescriptorPoolCreateInfo pool_info = {VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};",
    );
    e.line("pool_info.maxSets = 2;");
    e.line("pool_info.poolSizeCount = pvkCreateAccelerationStructureKHR ? 2 : 1;");
    e.line("pool_info.pPoolSizes = pool_sizes;");
    e.line("VkDescriptorPool descriptor_pool;");
    e.line("CHECK(vkCreateDescriptorPool(device, &pool_info, NULL, &descriptor_pool));");
    e.line(
        "VkDescriptorSetAllocateInfo set_alloc = {VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};",
    );
    e.line("set_alloc.descriptorPool = descriptor_pool;");
    e.line("set_alloc.descriptorSetCount = 1;");
    e.line("set_alloc.pSetLayouts = &set_layout;");
    e.line("VkDescriptorSet set;");
    e.line("CHECK(vkAllocateDescriptorSets(device, &set_alloc, &set));");
    e.line("VkDescriptorBufferInfo infos[3] = {{output.buffer, 0, VK_WHOLE_SIZE}, {rays.buffer, 0, VK_WHOLE_SIZE}, {callables.buffer, 0, VK_WHOLE_SIZE}};");
    e.line("VkWriteDescriptorSet writes[4];");
    e.line("memset(writes, 0, sizeof writes);");
    e.open("for (int i = 0; i < 3; i++) {");
    e.line("writes[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;");
    e.line("writes[i].dstSet = set;");
    e.line("writes[i].dstBinding = (uint32_t)i + 1;");
    e.line("writes[i].descriptorCount = 1;");
    e.line("writes[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;");
    e.line("writes[i].pBufferInfo = &infos[i];");
    e.close("}");
    if t.scene.is_some() {
        e.line("VkWriteDescriptorSetAccelerationStructureKHR structure_write = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET_ACCELERATION_STRUCTURE_KHR, NULL, 1, &top};");
        e.line("writes[3].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;");
        e.line("writes[3].pNext = &structure_write;");
        e.line("writes[3].dstSet = set;");
        e.line("writes[3].dstBinding = 0;");
        e.line("writes[3].descriptorCount = 1;");
        e.line("writes[3].descriptorType = VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR;");
        e.line("vkUpdateDescriptorSets(device, 4, writes, 0, NULL);");
    } else {
        e.line("vkUpdateDescriptorSets(device, 3, writes, 0, NULL);");
    }
    e.line("step(\"vkCreateBuffer output, rays, callables; vkAllocateDescriptorSets, vkUpdateDescriptorSets\");");
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
                e.line("printf(\"output:  read back; the model expects no words for this launch\\n\");");
            }
            Step::ReadBack { words } => {
                e.open("{");
                e.line("const uint32_t *got = read_words(&output);");
                e.line("uint64_t at = 0;");
                e.open(&format!(
                    "for (size_t r = 0; r < sizeof expected_runs / sizeof expected_runs[0] && at < {words} && output_ok; r++)"
                ));
                e.open("for (uint32_t k = 0; k < expected_runs[r][1]; k++, at++) {");
                e.open("if (got[at] != expected_runs[r][0]) {");
                e.line("printf(\"output:  DIFFERS from the model at word %llu: driver 0x%08x, model 0x%08x\\n\", (unsigned long long)at, got[at], expected_runs[r][0]);");
                e.line("output_ok = 0;");
                e.line("break;");
                e.close("}");
                e.close("}");
                e.indent -= 1;
                e.line("if (output_ok)");
                e.line("    printf(\"output:  matches the model (%llu words)\\n\", (unsigned long long)expected_words);");
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
