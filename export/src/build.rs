//! The C `main` of a build case: the device (with what the harness adds for its traced check), the
//! buffers with their memory images and the device addresses written into them, the acceleration
//! structures at their buffer ranges, the build infos, the sizes the device reports, then the plan's
//! steps with the indirect build recorded under the layer (never submitted); for a case run as valid,
//! then the traced check of its build ([`crate::check`]).

use crate::c::{self, Emitter};
use crate::{emit_device, emit_expectation, Expectation};
use harness::plan::build::{AddressOf, BuildPlan, GeometryDataPlan};
use harness::plan::{CallPlan, Step};
use model::flags::{BufferCreate, BufferUsage};
use model::world::{CommandBufferLevel, MemoryBinding};

/// `main` for a build plan, or what it cannot write.
pub(crate) fn emit(
    e: &mut Emitter,
    plan: &CallPlan,
    b: &BuildPlan,
    expect: &Expectation,
) -> Result<(), String> {
    for buf in &b.buffers {
        if buf.sparse {
            return Err(format!(
                "buffer `{}` is sparse; sparse buffers are not exported yet",
                buf.name
            ));
        }
        match buf.memory {
            MemoryBinding::Whole => {}
            MemoryBinding::Unbound if !buf.addressed && !buf.written => {}
            _ => {
                return Err(format!(
                    "buffer `{}` is not bound whole, which the harness realises only for unaddressed, unwritten buffers",
                    buf.name
                ))
            }
        }
    }
    if let Some(i) = b.infos.iter().position(|i| i.geometries.is_none()) {
        return Err(format!(
            "info {i} has a geometry type the harness does not realise"
        ));
    }
    let names: Vec<String> = b.buffers.iter().map(|x| x.name.clone()).collect();
    let addr = |a: &model::call::Address| -> Result<String, String> {
        c::address(a, &names, "world")
            .ok_or_else(|| format!("the call names a buffer the world lacks: {a:?}"))
    };
    for (k, buf) in b.buffers.iter().enumerate() {
        for (j, run) in buf.image.iter().enumerate() {
            if !c::trimmed(&run.bytes).is_empty() {
                c::bytes(e, &format!("image_{k}_{j}"), c::trimmed(&run.bytes));
            }
        }
    }
    let check = expect.build_check.as_ref();
    if let Some(c) = check {
        crate::check::data(e, c)?;
    }
    e.line("");
    e.open("int main(int argc, char **argv) {");
    e.line("/* ./repro [--records FILE]: FILE receives the traced check's records (little-endian words).");
    e.line(" * ./repro --judge FILE: judges the records in FILE against the model's tables, runs nothing. */");
    e.line("const char *records_path = argc > 2 && strcmp(argv[1], \"--records\") == 0 ? argv[2] : NULL;");
    e.line("(void)records_path;");
    if let Some(c) = check {
        e.line("record_of = \"check ray\";");
        e.line("if (argc > 2 && strcmp(argv[1], \"--judge\") == 0)");
        e.line(&format!(
            "    return judge_file(&launch_rules, argv[2], {}ull);",
            c.plan.rays.len()
        ));
    }
    emit_expectation(e, plan, expect);
    if let Some(c) = check {
        e.line(&format!(
            "printf(\"         then info 0 is built directly and the check's {} rays are traced at it and judged per ray\\n\");",
            c.plan.rays.len()
        ));
    }
    e.line("printf(\"         (judged with the sizes in the case file; rtconf replay judges with the device's)\\n\");");
    e.line("start(1);");
    e.line("printf(\"calls:\\n\");");
    emit_device(e, &plan.device, true);
    e.line(&format!("struct buffer world[{}];", b.buffers.len().max(1)));
    e.line("memset(world, 0, sizeof world);");
    for (k, buf) in b.buffers.iter().enumerate() {
        if buf.memory == MemoryBinding::Whole {
            e.line(&format!(
                "world[{k}] = make_buffer({}ull, {}, {}, {}); /* `{}` */",
                buf.size,
                c::flags(buf.usage, BufferUsage::NAMES),
                c::flags(buf.flags, BufferCreate::NAMES),
                model::call::BUFFER_PLACEMENT_ALIGNMENT,
                c::comment_safe(&buf.name)
            ));
        } else {
            e.line(&format!(
                "world[{k}].buffer = create_buffer({}ull, {}, {}); world[{k}].size = {}ull; /* `{}`: no memory bound */",
                buf.size,
                c::flags(buf.usage, BufferUsage::NAMES),
                c::flags(buf.flags, BufferCreate::NAMES),
                buf.size,
                c::comment_safe(&buf.name)
            ));
        }
        e.line(&format!(
            "step({});",
            c::string(&format!(
                "vkCreateBuffer `{}` ({} bytes)",
                buf.name, buf.size
            ))
        ));
    }
    e.line(&format!(
        "VkAccelerationStructureKHR structures[{}];",
        b.structures.len().max(1)
    ));
    e.line(&format!(
        "VkDeviceAddress structure_addresses[{}];",
        b.structures.len().max(1)
    ));
    e.line("memset(structure_addresses, 0, sizeof structure_addresses);");
    for (s, st) in b.structures.iter().enumerate() {
        let k = names
            .iter()
            .position(|n| *n == st.buffer)
            .ok_or_else(|| format!("structure `{}`: no buffer `{}`", st.name, st.buffer))?;
        e.open("{");
        e.line("VkAccelerationStructureCreateInfoKHR c = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_CREATE_INFO_KHR};");
        e.line(&format!("c.buffer = world[{k}].buffer;"));
        e.line(&format!("c.offset = {}ull;", st.offset));
        e.line(&format!("c.size = {}ull;", st.size));
        e.line(&format!(
            "c.type = (VkAccelerationStructureTypeKHR){};",
            st.ty
        ));
        e.line(&format!(
            "CHECK(pvkCreateAccelerationStructureKHR(device, &c, NULL, &structures[{s}]));"
        ));
        if b.buffers[k].memory == MemoryBinding::Whole {
            e.line(&format!("VkAccelerationStructureDeviceAddressInfoKHR a = {{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_DEVICE_ADDRESS_INFO_KHR, NULL, structures[{s}]}};"));
            e.line(&format!(
                "structure_addresses[{s}] = pvkGetAccelerationStructureDeviceAddressKHR(device, &a);"
            ));
        } else {
            e.line("/* On unbound memory: its address is never read (nor may it be asked). */");
        }
        e.line(&format!(
            "step({});",
            c::string(&format!(
                "vkCreateAccelerationStructureKHR `{}` on `{}`+{}, {} bytes",
                st.name, st.buffer, st.offset, st.size
            ))
        ));
        e.close("}");
    }
    for (k, buf) in b.buffers.iter().enumerate() {
        if buf.memory != MemoryBinding::Whole {
            continue;
        }
        e.line(&format!("write_image(&world[{k}], NULL, 0);"));
        for (j, run) in buf.image.iter().enumerate() {
            if !c::trimmed(&run.bytes).is_empty() {
                e.line(&format!(
                    "write_bytes(&world[{k}], {}ull, image_{k}_{j}, sizeof image_{k}_{j});",
                    run.offset
                ));
            }
        }
        for r in &buf.relocations {
            let value = match &r.target {
                AddressOf::Buffer { name, offset } => match names.iter().position(|n| n == name) {
                    Some(t) => format!("world[{t}].address + {offset}ull"),
                    None => "0".into(),
                },
                AddressOf::Structure { name } => {
                    match b.structures.iter().position(|s| s.name == *name) {
                        Some(s) => format!("structure_addresses[{s}]"),
                        None => "0".into(),
                    }
                }
            };
            e.line(&format!(
                "write_u64(&world[{k}], {}ull, {value}, {});",
                r.offset, r.len
            ));
        }
        if !buf.image.is_empty() {
            e.line(&format!(
                "step({});",
                c::string(&format!(
                    "write the memory image of `{}` ({} device address(es) in it)",
                    buf.name,
                    buf.relocations.len()
                ))
            ));
        }
    }
    infos(e, b, &addr)?;
    steps(e, b)?;
    match check {
        Some(c) => {
            crate::check::run(e, b, c)?;
            e.line("printf(\"verdict: %s\\n\", differ ? \"the layer departs from the model\" : output_differs ? \"the device's build departs from the model\" : \"the layer and the device do what the model expects\");");
            e.line("return differ || output_differs ? 1 : 0;");
        }
        None => {
            e.line("printf(\"verdict: %s\\n\", differ ? \"the layer departs from the model\" : \"the layer reports what the model expects\");");
            e.line("return differ ? 1 : 0;");
        }
    }
    e.close("}");
    Ok(())
}

fn infos(
    e: &mut Emitter,
    b: &BuildPlan,
    addr: &dyn Fn(&model::call::Address) -> Result<String, String>,
) -> Result<(), String> {
    let n = b.infos.len();
    e.line(&format!(
        "VkAccelerationStructureBuildGeometryInfoKHR infos[{}];",
        n.max(1)
    ));
    e.line("memset(infos, 0, sizeof infos);");
    let structure = |name: &Option<String>| -> String {
        match name
            .as_ref()
            .and_then(|n| b.structures.iter().position(|s| s.name == *n))
        {
            Some(s) => format!("structures[{s}]"),
            None => "VK_NULL_HANDLE".into(),
        }
    };
    for (i, info) in b.infos.iter().enumerate() {
        let geoms = info.geometries.as_deref().unwrap_or(&[]);
        e.line(&format!(
            "static VkAccelerationStructureGeometryKHR geometries_{i}[{}];",
            geoms.len().max(1)
        ));
        for (j, g) in geoms.iter().enumerate() {
            let at = format!("geometries_{i}[{j}]");
            e.line(&format!(
                "{at}.sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR; {at}.geometryType = (VkGeometryTypeKHR){}; {at}.flags = 0x{:x};",
                g.ty, g.flags
            ));
            match &g.data {
                GeometryDataPlan::Triangles {
                    vertex_format,
                    vertex_data,
                    vertex_stride,
                    max_vertex,
                    index_type,
                    index_data,
                    transform_data,
                } => {
                    let t = format!("{at}.geometry.triangles");
                    e.line(&format!("{t}.sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_TRIANGLES_DATA_KHR;"));
                    e.line(&format!("{t}.vertexFormat = (VkFormat){vertex_format};"));
                    e.line(&format!(
                        "{t}.vertexData.deviceAddress = {};",
                        addr(vertex_data)?
                    ));
                    e.line(&format!("{t}.vertexStride = {vertex_stride}ull;"));
                    e.line(&format!("{t}.maxVertex = {max_vertex};"));
                    e.line(&format!("{t}.indexType = (VkIndexType){index_type};"));
                    e.line(&format!(
                        "{t}.indexData.deviceAddress = {};",
                        addr(index_data)?
                    ));
                    e.line(&format!(
                        "{t}.transformData.deviceAddress = {};",
                        addr(transform_data)?
                    ));
                }
                GeometryDataPlan::Aabbs { data, stride } => {
                    let t = format!("{at}.geometry.aabbs");
                    e.line(&format!("{t}.sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_AABBS_DATA_KHR;"));
                    e.line(&format!("{t}.data.deviceAddress = {};", addr(data)?));
                    e.line(&format!("{t}.stride = {stride}ull;"));
                }
                GeometryDataPlan::Instances {
                    array_of_pointers,
                    data,
                } => {
                    let t = format!("{at}.geometry.instances");
                    e.line(&format!("{t}.sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_INSTANCES_DATA_KHR;"));
                    e.line(&format!(
                        "{t}.arrayOfPointers = {};",
                        if *array_of_pointers {
                            "VK_TRUE"
                        } else {
                            "VK_FALSE"
                        }
                    ));
                    e.line(&format!("{t}.data.deviceAddress = {};", addr(data)?));
                }
            }
        }
        let at = format!("infos[{i}]");
        e.line(&format!(
            "{at}.sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR;"
        ));
        e.line(&format!(
            "{at}.type = (VkAccelerationStructureTypeKHR){}; {at}.flags = 0x{:x}; {at}.mode = (VkBuildAccelerationStructureModeKHR){};",
            info.ty, info.flags, info.mode
        ));
        e.line(&format!(
            "{at}.srcAccelerationStructure = {}; {at}.dstAccelerationStructure = {};",
            structure(&info.src),
            structure(&info.dst)
        ));
        e.line(&format!(
            "{at}.geometryCount = {}; {at}.pGeometries = geometries_{i};",
            geoms.len()
        ));
        e.line(&format!(
            "{at}.scratchData.deviceAddress = {};",
            addr(&info.scratch)?
        ));
    }
    for (i, m) in b.max_primitive_counts.iter().enumerate() {
        e.line(&format!(
            "static const uint32_t maxima_{i}[{}] = {{{}}};",
            m.len().max(1),
            if m.is_empty() {
                "0".to_string()
            } else {
                m.iter()
                    .map(|x| x.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            }
        ));
    }
    let p = b.max_primitive_counts.len();
    e.line(&format!(
        "const uint32_t *maxima[{}] = {{{}}};",
        p.max(1),
        if p == 0 {
            "NULL".to_string()
        } else {
            (0..p)
                .map(|i| format!("maxima_{i}"))
                .collect::<Vec<_>>()
                .join(", ")
        }
    ));
    // The sizes the device reports for each info with its maxima (when every maxima list matches its
    // geometries, as the harness asks them).
    let asks = b.infos.len() == b.max_primitive_counts.len()
        && b.infos
            .iter()
            .zip(&b.max_primitive_counts)
            .all(|(i, m)| i.geometries.as_ref().map_or(0, |g| g.len()) == m.len());
    if asks {
        for i in 0..n {
            e.open("{");
            e.line("VkAccelerationStructureBuildSizesInfoKHR s = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_SIZES_INFO_KHR};");
            e.line(&format!("pvkGetAccelerationStructureBuildSizesKHR(device, VK_ACCELERATION_STRUCTURE_BUILD_TYPE_DEVICE_KHR, &infos[{i}], maxima[{i}], &s);"));
            e.line(&format!("printf(\"  vkGetAccelerationStructureBuildSizesKHR for info {i}: structure %llu, build scratch %llu, update scratch %llu bytes\\n\", (unsigned long long)s.accelerationStructureSize, (unsigned long long)s.buildScratchSize, (unsigned long long)s.updateScratchSize);"));
            e.close("}");
        }
    }
    let a: Vec<String> = b
        .indirect_addresses
        .iter()
        .map(addr)
        .collect::<Result<_, _>>()?;
    e.line(&format!(
        "VkDeviceAddress indirect[{}] = {{{}}};",
        a.len().max(1),
        if a.is_empty() {
            "0".into()
        } else {
            a.join(", ")
        }
    ));
    e.line(&format!(
        "uint32_t strides[{}] = {{{}}};",
        b.indirect_strides.len().max(1),
        if b.indirect_strides.is_empty() {
            "0".into()
        } else {
            b.indirect_strides
                .iter()
                .map(|s| s.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        }
    ));
    Ok(())
}

fn steps(e: &mut Emitter, b: &BuildPlan) -> Result<(), String> {
    let secondary = b.level == CommandBufferLevel::Secondary;
    e.line(&format!(
        "VkCommandBuffer cb = {};",
        if secondary { "secondary" } else { "primary" }
    ));
    if b.in_render_pass {
        e.line("make_render_pass();");
    }
    e.line("int differ = 0;");
    let mut called = false;
    for s in &b.steps {
        e.line(&format!(
            "step({});",
            c::string(&harness::plan::step_text(s))
        ));
        match s {
            Step::Reset { .. } => e.line("CHECK(vkResetCommandBuffer(cb, 0));"),
            Step::Begin {
                continue_render_pass,
                ..
            } => {
                e.open("{");
                e.line("VkCommandBufferInheritanceInfo inherit = {VK_STRUCTURE_TYPE_COMMAND_BUFFER_INHERITANCE_INFO};");
                e.line("VkCommandBufferBeginInfo begin = {VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};");
                e.line("begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;");
                if *continue_render_pass {
                    e.line("inherit.renderPass = render_pass; inherit.subpass = 0; inherit.framebuffer = framebuffer;");
                    e.line("begin.flags |= VK_COMMAND_BUFFER_USAGE_RENDER_PASS_CONTINUE_BIT;");
                }
                if secondary {
                    e.line("begin.pInheritanceInfo = &inherit;");
                }
                e.line("(void)inherit;");
                e.line("CHECK(vkBeginCommandBuffer(cb, &begin));");
                e.close("}");
            }
            Step::BeginRenderPass => e.line("begin_render_pass(cb, VK_SUBPASS_CONTENTS_INLINE);"),
            Step::EndRenderPass => e.line("vkCmdEndRenderPass(cb);"),
            // After the call a recording buffer is ended only to be reset.
            Step::End if called => e.line("vkEndCommandBuffer(cb);"),
            Step::End => e.line("CHECK(vkEndCommandBuffer(cb));"),
            Step::SubmitToInvalidate => {
                if secondary {
                    e.line("begin_one_time(primary);");
                    if b.in_render_pass {
                        e.line("begin_render_pass(primary, VK_SUBPASS_CONTENTS_SECONDARY_COMMAND_BUFFERS);");
                    }
                    e.line("vkCmdExecuteCommands(primary, 1, &cb);");
                    if b.in_render_pass {
                        e.line("vkCmdEndRenderPass(primary);");
                    }
                    e.line("CHECK(vkEndCommandBuffer(primary));");
                    e.line("submit_and_wait(primary);");
                } else {
                    e.line("submit_and_wait(cb);");
                }
            }
            Step::Call { .. } => {
                e.line("clear_messages();");
                e.line(
                    "drop_calls = 1; /* the messenger returns VK_TRUE: the layer drops the call */",
                );
                e.line(&format!(
                    "pvkCmdBuildAccelerationStructuresIndirectKHR(cb, {}, infos, indirect, strides, maxima);",
                    b.infos.len()
                ));
                e.line("drop_calls = 0;");
                e.line("printf(\"layer's messages:\\n\");");
                e.line("differ = report_layer(model_vuids, model_vuid_count);");
                e.line("clear_messages();");
                called = true;
            }
            other => {
                return Err(format!(
                    "a build plan holds the step `{}`",
                    harness::plan::step_text(other)
                ))
            }
        }
    }
    Ok(())
}
