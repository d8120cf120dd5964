//! The traced check of a valid build case in C, as `harness::accel_check` runs it: the case's first
//! info built directly (vkCmdBuildAccelerationStructuresKHR) with the ranges the model reads from
//! memory — a top-level case's one-triangle bottom level `blas` first —, a bottom-level result put
//! into a one-instance top level, then the check's rays traced at it — by the ray query compute shader
//! (`harness/shaders/check_query.comp`), or where the device lacks ray query (or
//! `RTCONF_REPRO_CHECK=pipeline` asks) by the pipeline of `harness/shaders/check.*` —, each writing its
//! 28-word record, read back and judged against what the model allows the ray (`judge_records` in
//! `runtime.c`). The device's build of such a case
//! is what a driver bug in it shows: a ray that misses a primitive the model must hit.

use crate::c::{self, Emitter};
use crate::BuildCheckExpectation;
use harness::plan::build::BuildPlan;
use harness::plan::check::{BLAS_TRIANGLE, TOP_LEVEL_BLAS};
use model::tracer::record::RayRecord;

/// The index of structure `name` among the plan's structures (`structures[]` in the program).
fn structure_index(b: &BuildPlan, name: Option<&str>) -> Result<usize, String> {
    let name = name.ok_or("info 0 has no destination structure")?;
    b.structures
        .iter()
        .position(|s| s.name == name)
        .ok_or_else(|| format!("the traced check needs structure `{name}`, which the world lacks"))
}

/// The check's data, before `main`: the compute shader's SPIR-V, the rays, the sphere table, the
/// record every ray starts from, a top-level case's one-triangle bottom level, and the model's tables.
pub(crate) fn data(e: &mut Emitter, check: &BuildCheckExpectation) -> Result<(), String> {
    if check.allowed.len() != check.plan.rays.len() {
        return Err(format!(
            "the traced check has {} rays and {} expectations",
            check.plan.rays.len(),
            check.allowed.len()
        ));
    }
    let spirv = harness::plan::check::ray_query_spirv().map_err(|e| e.to_string())?;
    let [raygen, miss, closest_hit, intersection] =
        harness::plan::check::pipeline_spirv().map_err(|e| e.to_string())?;
    e.line("/* The traced check: the ray query shader (harness/shaders/check_query.comp) and the pipeline's");
    e.line(" * raygen, miss, closest-hit and intersection shaders (harness/shaders/check.*) as SPIR-V, the");
    e.line(" * check's rays (origin and tmin, direction and tmax per ray), the sphere table of the built boxes");
    e.line(" * (per geometry its first sphere, then centre and radius per box), and each ray's first record. */");
    c::words(e, "check_spirv", &spirv);
    c::words(e, "check_raygen", &raygen);
    c::words(e, "check_miss", &miss);
    c::words(e, "check_closest_hit", &closest_hit);
    c::words(e, "check_intersection", &intersection);
    c::le_words(e, "check_rays", &check.plan.ray_bytes());
    c::le_words(e, "check_spheres", &check.plan.spheres);
    c::words(e, "record_prefill", &RayRecord::PREFILL);
    if check.plan.top {
        let triangle: Vec<u32> = BLAS_TRIANGLE.iter().map(|f| f.to_bits()).collect();
        c::words(e, "blas_triangle", &triangle);
    }
    crate::records::tables(
        e,
        check.allowed.iter(),
        "ray of the build's traced check (model::accel::check::BuildCheck)",
    );
    Ok(())
}

/// The check in `main`, after the case's own steps: sets `output_differs` (declared here) when a
/// record breaks what the model allows; a device with neither ray query nor a ray tracing pipeline
/// is told so and checked no further.
pub(crate) fn run(
    e: &mut Emitter,
    b: &BuildPlan,
    check: &BuildCheckExpectation,
) -> Result<(), String> {
    let plan = &check.plan;
    let dst = structure_index(b, b.infos.first().and_then(|i| i.dst.as_deref()))?;
    let blas = if plan.top {
        Some(structure_index(b, Some(TOP_LEVEL_BLAS))?)
    } else {
        None
    };
    let rays = plan.rays.len();
    e.line("int output_differs = 0;");
    e.line("printf(\"check:   the harness's traced check: info 0 built directly with the ranges the model reads, its rays traced with %s\\n\", check_by_query ? \"ray query\" : \"a ray tracing pipeline\");");
    e.open("if (!check_by_query && !check_by_pipeline) {");
    e.line("printf(\"output:  not checked: the device has neither VK_KHR_ray_query nor VK_KHR_ray_tracing_pipeline\\n\");");
    e.close("}");
    e.open("else {");
    e.line("const VkBufferUsageFlags build_input = VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT;");
    if !plan.top {
        e.line("const VkBufferUsageFlags storage_usage = VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_STORAGE_BIT_KHR | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT;");
    }
    e.line("const VkBufferUsageFlags scratch_usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT;");
    e.line("VkPhysicalDeviceAccelerationStructurePropertiesKHR as_props = {VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_PROPERTIES_KHR};");
    e.line(
        "VkPhysicalDeviceProperties2 props2 = {VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};",
    );
    e.line("props2.pNext = &as_props;");
    e.line("vkGetPhysicalDeviceProperties2(physical, &props2);");
    e.line("VkDeviceSize scratch_align = as_props.minAccelerationStructureScratchOffsetAlignment > 256 ? as_props.minAccelerationStructureScratchOffsetAlignment : 256;");
    e.line("clear_messages();");
    if let Some(k) = blas {
        blas_triangle(e, k);
    }
    direct_build(e, plan, dst);
    e.line("VkAccelerationStructureKHR check_scene;");
    if plan.top {
        e.line(&format!("check_scene = structures[{dst}];"));
    } else {
        one_instance_top(e, dst);
    }
    trace_rays(e, rays, plan.procedural);
    e.close("}");
    Ok(())
}

/// The one-triangle bottom level a top-level case's instances reference, built into `structures[k]`.
fn blas_triangle(e: &mut Emitter, k: usize) {
    e.open("{");
    e.line("struct buffer vertices = make_buffer(sizeof blas_triangle, build_input, 0, 256);");
    e.line("write_bytes(&vertices, 0, blas_triangle, sizeof blas_triangle);");
    e.line("struct buffer scratch = make_buffer(65536, scratch_usage, 0, scratch_align);");
    e.line("VkAccelerationStructureGeometryKHR g = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};");
    e.line("g.geometryType = VK_GEOMETRY_TYPE_TRIANGLES_KHR;");
    e.line("g.geometry.triangles.sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_TRIANGLES_DATA_KHR;");
    e.line("g.geometry.triangles.vertexFormat = VK_FORMAT_R32G32B32_SFLOAT;");
    e.line("g.geometry.triangles.vertexData.deviceAddress = vertices.address;");
    e.line("g.geometry.triangles.vertexStride = 12;");
    e.line("g.geometry.triangles.maxVertex = 2;");
    e.line("g.geometry.triangles.indexType = VK_INDEX_TYPE_NONE_KHR;");
    e.line("VkAccelerationStructureBuildGeometryInfoKHR info = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};");
    e.line("info.type = VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR;");
    e.line("info.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;");
    e.line("info.geometryCount = 1;");
    e.line("info.pGeometries = &g;");
    e.line(&format!("info.dstAccelerationStructure = structures[{k}];"));
    e.line("info.scratchData.deviceAddress = scratch.address;");
    e.line("VkAccelerationStructureBuildRangeInfoKHR range = {1, 0, 0, 0};");
    e.line("build_and_wait(&info, &range);");
    e.line(&format!(
        "step({});",
        c::string(&format!(
            "vkCmdBuildAccelerationStructuresKHR: the one-triangle bottom level `{TOP_LEVEL_BLAS}` the instances reference; submitted and waited for"
        ))
    ));
    e.close("}");
}

/// Info 0 built directly with the model's ranges into `structures[dst]`; the layer's messages on it
/// are printed, and any makes the program's verdict differ.
fn direct_build(e: &mut Emitter, plan: &harness::plan::check::CheckPlan, dst: usize) {
    let ranges: Vec<String> = plan
        .ranges
        .iter()
        .map(|r| {
            format!(
                "{{{}, {}, {}, {}}}",
                r.primitive_count, r.primitive_offset, r.first_vertex, r.transform_offset
            )
        })
        .collect();
    e.open("{");
    e.line("/* The ranges the model reads from the case's indirect buffer, one per geometry of info 0. */");
    e.line(&format!(
        "VkAccelerationStructureBuildRangeInfoKHR check_ranges[{}] = {{{}}};",
        ranges.len().max(1),
        if ranges.is_empty() {
            "{0, 0, 0, 0}".to_string()
        } else {
            ranges.join(", ")
        }
    ));
    e.line("build_and_wait(&infos[0], check_ranges);");
    e.line(&format!(
        "step({});",
        c::string(&format!(
            "vkCmdBuildAccelerationStructuresKHR: info 0 into structures[{dst}] with the {} range(s) the model reads; submitted and waited for",
            plan.ranges.len()
        ))
    ));
    e.line("if (report_own_calls(\"the direct build\")) differ = 1;");
    e.close("}");
}

/// A top level of one instance (identity transform, custom index 0, mask 0xFF, record offset 0, no
/// flags) of `structures[dst]`, as `check_scene`.
fn one_instance_top(e: &mut Emitter, dst: usize) {
    e.open("{");
    e.line("VkAccelerationStructureInstanceKHR one = {{{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}}}, 0, 0xFF, 0, 0, 0};");
    e.line(&format!(
        "one.accelerationStructureReference = structure_addresses[{dst}];"
    ));
    e.line("struct buffer instances = make_buffer(sizeof one, build_input, 0, 256);");
    e.line("write_bytes(&instances, 0, &one, sizeof one);");
    e.line("VkAccelerationStructureGeometryKHR g = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};");
    e.line("g.geometryType = VK_GEOMETRY_TYPE_INSTANCES_KHR;");
    e.line("g.geometry.instances.sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_INSTANCES_DATA_KHR;");
    e.line("g.geometry.instances.data.deviceAddress = instances.address;");
    e.line("VkAccelerationStructureBuildGeometryInfoKHR info = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};");
    e.line("info.type = VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR;");
    e.line("info.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;");
    e.line("info.geometryCount = 1;");
    e.line("info.pGeometries = &g;");
    e.line("uint32_t count = 1;");
    e.line("VkAccelerationStructureBuildSizesInfoKHR sizes = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_SIZES_INFO_KHR};");
    e.line("pvkGetAccelerationStructureBuildSizesKHR(device, VK_ACCELERATION_STRUCTURE_BUILD_TYPE_DEVICE_KHR, &info, &count, &sizes);");
    e.line("struct buffer storage = make_buffer(sizes.accelerationStructureSize, storage_usage, 0, 256);");
    e.line("struct buffer scratch = make_buffer(sizes.buildScratchSize ? sizes.buildScratchSize : 1, scratch_usage, 0, scratch_align);");
    e.line("VkAccelerationStructureCreateInfoKHR c = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_CREATE_INFO_KHR};");
    e.line("c.buffer = storage.buffer;");
    e.line("c.size = sizes.accelerationStructureSize;");
    e.line("c.type = VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR;");
    e.line("CHECK(pvkCreateAccelerationStructureKHR(device, &c, NULL, &check_scene));");
    e.line("info.dstAccelerationStructure = check_scene;");
    e.line("info.scratchData.deviceAddress = scratch.address;");
    e.line("VkAccelerationStructureBuildRangeInfoKHR range = {1, 0, 0, 0};");
    e.line("build_and_wait(&info, &range);");
    e.line(&format!(
        "step({});",
        c::string(&format!(
            "vkCmdBuildAccelerationStructuresKHR: a top level of one instance of structures[{dst}] (identity, mask 0xFF); submitted and waited for"
        ))
    ));
    e.close("}");
}

/// The rays traced at `check_scene`, one invocation each, with ray query or the pipeline (every
/// geometry through hit record 0: the triangles' hit group, or the procedural one for a build of
/// boxes); their records read back, written to `records_path` when given, and judged.
fn trace_rays(e: &mut Emitter, rays: usize, procedural: bool) {
    e.open("{");
    e.line("const VkBufferUsageFlags check_usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT;");
    e.line("struct buffer rays = make_buffer(sizeof check_rays, check_usage, 0, 1);");
    e.line("write_bytes(&rays, 0, check_rays, sizeof check_rays);");
    e.line(&format!(
        "struct buffer records = make_buffer({}ull, check_usage, 0, 1);",
        (rays.max(1) * RayRecord::WORDS * 4)
    ));
    e.line(&format!(
        "for (uint64_t i = 0; i < {rays}ull; i++) write_bytes(&records, i * RECORD_WORDS * 4, record_prefill, sizeof record_prefill);"
    ));
    e.line("struct buffer spheres = make_buffer(sizeof check_spheres, check_usage, 0, 1);");
    e.line("write_bytes(&spheres, 0, check_spheres, sizeof check_spheres);");
    e.line("/* Binding 0: the structure; 1: the rays; 2: the records; 3: the sphere table. */");
    e.line("VkDescriptorSetLayoutBinding bindings[4];");
    e.line("memset(bindings, 0, sizeof bindings);");
    e.open("for (uint32_t i = 0; i < 4; i++) {");
    e.line("bindings[i].binding = i;");
    e.line("bindings[i].descriptorType = i == 0 ? VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;");
    e.line("bindings[i].descriptorCount = 1;");
    e.line("bindings[i].stageFlags = check_by_query ? VK_SHADER_STAGE_COMPUTE_BIT : VK_SHADER_STAGE_RAYGEN_BIT_KHR | VK_SHADER_STAGE_INTERSECTION_BIT_KHR;");
    e.close("}");
    e.line("VkDescriptorSetLayoutCreateInfo layout_info = {VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};");
    e.line("layout_info.bindingCount = 4;");
    e.line("layout_info.pBindings = bindings;");
    e.line("VkDescriptorSetLayout set_layout;");
    e.line("CHECK(vkCreateDescriptorSetLayout(device, &layout_info, NULL, &set_layout));");
    e.line("VkDescriptorPoolSize pool_sizes[2] = {{VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR, 1}, {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 3}};");
    e.line("VkDescriptorSet set = one_set(set_layout, pool_sizes, 2, 1);");
    e.line("VkDescriptorBufferInfo buffer_infos[3] = {{rays.buffer, 0, VK_WHOLE_SIZE}, {records.buffer, 0, VK_WHOLE_SIZE}, {spheres.buffer, 0, VK_WHOLE_SIZE}};");
    e.line("VkWriteDescriptorSetAccelerationStructureKHR structure_write = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET_ACCELERATION_STRUCTURE_KHR, NULL, 1, &check_scene};");
    e.line("VkWriteDescriptorSet writes[4];");
    e.line("memset(writes, 0, sizeof writes);");
    e.open("for (uint32_t i = 0; i < 4; i++) {");
    e.line("writes[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;");
    e.line("writes[i].dstSet = set;");
    e.line("writes[i].dstBinding = i;");
    e.line("writes[i].descriptorCount = 1;");
    e.line("writes[i].descriptorType = bindings[i].descriptorType;");
    e.line("if (i == 0) writes[i].pNext = &structure_write; else writes[i].pBufferInfo = &buffer_infos[i - 1];");
    e.close("}");
    e.line("vkUpdateDescriptorSets(device, 4, writes, 0, NULL);");
    e.line("VkPipelineLayoutCreateInfo pipeline_layout_info = {VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};");
    e.line("pipeline_layout_info.setLayoutCount = 1;");
    e.line("pipeline_layout_info.pSetLayouts = &set_layout;");
    e.line("VkPipelineLayout pipeline_layout;");
    e.line("CHECK(vkCreatePipelineLayout(device, &pipeline_layout_info, NULL, &pipeline_layout));");
    e.open("if (check_by_query) {");
    e.line("VkShaderModuleCreateInfo module_info = {VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};");
    e.line("module_info.codeSize = sizeof check_spirv;");
    e.line("module_info.pCode = check_spirv;");
    e.line("VkShaderModule module;");
    e.line("CHECK(vkCreateShaderModule(device, &module_info, NULL, &module));");
    e.line(
        "VkComputePipelineCreateInfo compute = {VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};",
    );
    e.line("compute.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;");
    e.line("compute.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;");
    e.line("compute.stage.module = module;");
    e.line("compute.stage.pName = \"main\";");
    e.line("compute.layout = pipeline_layout;");
    e.line("VkPipeline check_pipeline;");
    e.line("CHECK(vkCreateComputePipelines(device, VK_NULL_HANDLE, 1, &compute, NULL, &check_pipeline));");
    e.line("begin_one_time(primary);");
    e.line("vkCmdBindPipeline(primary, VK_PIPELINE_BIND_POINT_COMPUTE, check_pipeline);");
    e.line("vkCmdBindDescriptorSets(primary, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_layout, 0, 1, &set, 0, NULL);");
    e.line(&format!("vkCmdDispatch(primary, {rays}, 1, 1);"));
    e.line("memory_barrier(primary, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_HOST_READ_BIT);");
    e.line("CHECK(vkEndCommandBuffer(primary));");
    e.line("submit_and_wait(primary);");
    e.line(&format!(
        "step(\"vkCmdDispatch: the check's {rays} ray(s) traced with ray query, one invocation each; submitted and waited for\");"
    ));
    e.close("}");
    e.open("else {");
    pipeline_trace(e, rays, procedural);
    e.close("}");
    e.line("if (report_own_calls(\"the check's rays\")) differ = 1;");
    e.line("const uint32_t *got = read_words(&records);");
    e.line(&format!(
        "if (records_path) save_records(records_path, got, {}ull);",
        rays * RayRecord::WORDS
    ));
    e.line(&format!(
        "uint64_t failed = judge_records(&launch_rules, got, {rays}ull);"
    ));
    e.line("output_differs = failed != 0;");
    e.line("if (failed)");
    e.line("    printf(\"output:  DIFFERS from the model at %llu ray(s)\\n\", (unsigned long long)failed);");
    e.line("else");
    e.line(&format!(
        "    printf(\"output:  matches the model ({rays} rays)\\n\");"
    ));
    e.close("}");
}

/// The pipeline path of [`trace_rays`] (as `harness::accel_check::pipeline` makes it): raygen, miss,
/// closest-hit and intersection stages; groups raygen, miss, triangles (closest-hit) and procedural
/// (closest-hit and intersection); a table of three regions (raygen, miss, the hit group) each one
/// record of the handle size aligned to the handle alignment, at base-aligned offsets.
fn pipeline_trace(e: &mut Emitter, rays: usize, procedural: bool) {
    e.line("VkPhysicalDeviceRayTracingPipelinePropertiesKHR rt_props = {VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_PROPERTIES_KHR};");
    e.line(
        "VkPhysicalDeviceProperties2 rt_props2 = {VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};",
    );
    e.line("rt_props2.pNext = &rt_props;");
    e.line("vkGetPhysicalDeviceProperties2(physical, &rt_props2);");
    e.line("const uint32_t *const codes[4] = {check_raygen, check_miss, check_closest_hit, check_intersection};");
    e.line("const size_t sizes[4] = {sizeof check_raygen, sizeof check_miss, sizeof check_closest_hit, sizeof check_intersection};");
    e.line("const VkShaderStageFlagBits kinds[4] = {VK_SHADER_STAGE_RAYGEN_BIT_KHR, VK_SHADER_STAGE_MISS_BIT_KHR, VK_SHADER_STAGE_CLOSEST_HIT_BIT_KHR, VK_SHADER_STAGE_INTERSECTION_BIT_KHR};");
    e.line("VkPipelineShaderStageCreateInfo stages[4];");
    e.line("memset(stages, 0, sizeof stages);");
    e.open("for (int i = 0; i < 4; i++) {");
    e.line("VkShaderModuleCreateInfo module_info = {VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};");
    e.line("module_info.codeSize = sizes[i];");
    e.line("module_info.pCode = codes[i];");
    e.line("stages[i].sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;");
    e.line("stages[i].stage = kinds[i];");
    e.line("stages[i].pName = \"main\";");
    e.line("CHECK(vkCreateShaderModule(device, &module_info, NULL, &stages[i].module));");
    e.close("}");
    e.line("VkRayTracingShaderGroupCreateInfoKHR groups[4];");
    e.line("memset(groups, 0, sizeof groups);");
    e.line("const VkRayTracingShaderGroupTypeKHR group_types[4] = {VK_RAY_TRACING_SHADER_GROUP_TYPE_GENERAL_KHR, VK_RAY_TRACING_SHADER_GROUP_TYPE_GENERAL_KHR, VK_RAY_TRACING_SHADER_GROUP_TYPE_TRIANGLES_HIT_GROUP_KHR, VK_RAY_TRACING_SHADER_GROUP_TYPE_PROCEDURAL_HIT_GROUP_KHR};");
    e.open("for (uint32_t i = 0; i < 4; i++) {");
    e.line("groups[i].sType = VK_STRUCTURE_TYPE_RAY_TRACING_SHADER_GROUP_CREATE_INFO_KHR;");
    e.line("groups[i].type = group_types[i];");
    e.line("groups[i].generalShader = i < 2 ? i : VK_SHADER_UNUSED_KHR;");
    e.line("groups[i].closestHitShader = i < 2 ? VK_SHADER_UNUSED_KHR : 2;");
    e.line("groups[i].anyHitShader = VK_SHADER_UNUSED_KHR;");
    e.line("groups[i].intersectionShader = i == 3 ? 3 : VK_SHADER_UNUSED_KHR;");
    e.close("}");
    e.line("VkRayTracingPipelineCreateInfoKHR rt_info = {VK_STRUCTURE_TYPE_RAY_TRACING_PIPELINE_CREATE_INFO_KHR};");
    e.line("rt_info.stageCount = 4;");
    e.line("rt_info.pStages = stages;");
    e.line("rt_info.groupCount = 4;");
    e.line("rt_info.pGroups = groups;");
    e.line("rt_info.maxPipelineRayRecursionDepth = 1;");
    e.line("rt_info.layout = pipeline_layout;");
    e.line("VkPipeline check_pipeline;");
    e.line("CHECK(pvkCreateRayTracingPipelinesKHR(device, VK_NULL_HANDLE, VK_NULL_HANDLE, 1, &rt_info, NULL, &check_pipeline));");
    e.line("const VkDeviceSize handle = rt_props.shaderGroupHandleSize;");
    e.line("uint8_t handles[4 * 256];");
    e.line("if (handle == 0 || handle > 256) { fprintf(stderr, \"rtconf reproducer: a shader group handle of %llu bytes\\n\", (unsigned long long)handle); return 2; }");
    e.line("CHECK(pvkGetRayTracingShaderGroupHandlesKHR(device, check_pipeline, 0, 4, (size_t)(4 * handle), handles));");
    e.line("VkDeviceSize handle_align = rt_props.shaderGroupHandleAlignment ? rt_props.shaderGroupHandleAlignment : 1;");
    e.line("VkDeviceSize base_align = rt_props.shaderGroupBaseAlignment ? rt_props.shaderGroupBaseAlignment : 1;");
    e.line("VkDeviceSize record = (handle + handle_align - 1) / handle_align * handle_align;");
    e.line("VkDeviceSize region = (record + base_align - 1) / base_align * base_align;");
    e.line("struct buffer table = make_buffer(3 * region, VK_BUFFER_USAGE_SHADER_BINDING_TABLE_BIT_KHR | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT, 0, base_align);");
    e.line("write_bytes(&table, 0, handles, (size_t)handle);");
    e.line("write_bytes(&table, region, handles + handle, (size_t)handle);");
    e.line(&format!(
        "write_bytes(&table, 2 * region, handles + {} * handle, (size_t)handle); /* the {} hit group */",
        if procedural { 3 } else { 2 },
        if procedural { "procedural" } else { "triangles" }
    ));
    e.line("VkStridedDeviceAddressRegionKHR raygen_region = {table.address, record, record};");
    e.line(
        "VkStridedDeviceAddressRegionKHR miss_region = {table.address + region, record, record};",
    );
    e.line("VkStridedDeviceAddressRegionKHR hit_region = {table.address + 2 * region, record, record};");
    e.line("VkStridedDeviceAddressRegionKHR callable_region = {0, 0, 0};");
    e.line("begin_one_time(primary);");
    e.line("vkCmdBindPipeline(primary, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, check_pipeline);");
    e.line("vkCmdBindDescriptorSets(primary, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, pipeline_layout, 0, 1, &set, 0, NULL);");
    e.line(&format!(
        "pvkCmdTraceRaysKHR(primary, &raygen_region, &miss_region, &hit_region, &callable_region, {rays}, 1, 1);"
    ));
    e.line("memory_barrier(primary, VK_PIPELINE_STAGE_RAY_TRACING_SHADER_BIT_KHR, VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_HOST_READ_BIT);");
    e.line("CHECK(vkEndCommandBuffer(primary));");
    e.line("submit_and_wait(primary);");
    e.line(&format!(
        "step(\"vkCmdTraceRaysKHR: the check's {rays} ray(s) traced with a ray tracing pipeline, one launch ID each; submitted and waited for\");"
    ));
}
