//! Applying a mutation: the plan edited (or the realised world, for what a plan cannot say) so the case
//! breaks exactly its rule, with the co-violations declared.

use super::*;

/// An edit of the realised world and call, made after layout.
type PostEdit = Box<dyn FnOnce(&mut World, &mut Call)>;

/// The VUID of `scope` with `tag`, if the loaded registry has it (any status).
fn registry_vuid(rules: &RuleSet, scope: &str, tag: &str) -> Option<String> {
    rules
        .rows
        .iter()
        .find(|r| r.scope == scope && r.vuid.rsplit('-').next() == Some(tag))
        .map(|r| r.vuid.clone())
}

/// The rule that a pipeline is bound, of `scope`, as the loaded registry names it: 08607 where shaderObject
/// is enabled, 08606 (02700 in older registries) where it is not.
fn no_pipeline_vuids(plan: &Plan, rules: &RuleSet, scope: &str) -> Vec<String> {
    let tags: &[&str] = if plan.device.features.contains("shaderObject") {
        &["08607"]
    } else {
        &["02700", "08606"]
    };
    tags.iter()
        .filter_map(|tag| registry_vuid(rules, scope, tag))
        .collect()
}

/// A record handle that is valid for an unreached or miss-reached miss record.
fn miss_handle(plan: &mut Plan) -> HandleRef {
    let gi = GroupIndex::of(&plan.groups);
    if let Some(&g) = gi.miss.first() {
        return HandleRef::Group(g);
    }
    if plan
        .flags
        .contains(PipelineCreate::RAY_TRACING_NO_NULL_MISS_SHADERS_BIT_KHR)
    {
        plan.groups.push(ShaderGroup::General {
            stage: GeneralStage::Miss,
        });
        return HandleRef::Group(plan.groups.len() as u32 - 1);
    }
    HandleRef::Zero
}

/// Makes sure a table has at least one record (unreached records hold valid handles).
fn ensure_used(plan: &mut Plan, t: Table) {
    if plan.tables[t as usize].used() {
        return;
    }
    let h = match t {
        Table::Raygen => HandleRef::Group(0),
        Table::Miss => miss_handle(plan),
        Table::Hit | Table::Callable => HandleRef::Zero,
    };
    plan.tables[t as usize].records.push(h);
}

/// Every dimension at least 1 and enough launch IDs that every ray is traced.
fn ensure_launch(plan: &mut Plan) {
    for d in plan.dims.iter_mut() {
        *d = (*d).max(1);
    }
    let rays = plan.launch.ray_count() as u32;
    plan.dims[0] = plan.dims[0].max(rays);
}

/// Appends a ray that misses and reaches a fresh miss record holding `h`.
fn add_miss_ray(plan: &mut Plan, h: HandleRef) {
    let table = &mut plan.tables[Table::Miss as usize];
    let idx = table.records.len() as u32;
    table.records.push(h);
    plan.launch.rays.push(model::scene::Ray {
        miss_index: idx,
        ..crate::aim::ray_beside(crate::aim::PROBE_MASK)
    });
    ensure_launch(plan);
}

/// Appends an instance with one geometry of `kind` and a ray that reaches a fresh hit record holding `h`.
fn add_hit_ray(plan: &mut Plan, kind: GeometryKind, h: HandleRef) {
    let table = &mut plan.tables[Table::Hit as usize];
    let idx = table.records.len() as u32;
    table.records.push(h);
    let instance = crate::aim::add_instance(&mut plan.launch, &[kind], idx, crate::aim::PROBE_MASK);
    plan.launch
        .rays
        .push(crate::aim::ray_at(instance, 0, crate::aim::PROBE_MASK));
    ensure_launch(plan);
}

/// Shrinks a recursion that the appended ray would push past the pipeline's maximum.
fn keep_recursion(plan: &mut Plan) {
    let depth = plan.launch.recursion_depth();
    if depth > plan.max_recursion_depth {
        plan.max_recursion_depth = depth;
    }
}

/// An alignment breaker for `align`: 1 byte, align - 1, then the middle.
fn misalignment(align: u64, knob: u32) -> Option<u64> {
    if align <= 1 {
        return None;
    }
    Some(match knob % 3 {
        0 => 1,
        1 => align - 1,
        _ => (align / 2).max(1),
    })
}

fn buffer_mut<'w>(world: &'w mut World, name: &str) -> &'w mut model::world::Buffer {
    world
        .buffers
        .iter_mut()
        .find(|b| b.name == name)
        .expect("realised plans name their buffers")
}

/// Applies a mutation to a valid plan and realises it.
pub fn apply(m: Mutation, mut plan: Plan, input: &MutationInput) -> Result<Mutated, GenError> {
    // Resource mutations edit the realised world.
    if let Mutation::Resource(r) = m {
        return crate::resources::apply(r, plan, input);
    }
    supported(m, input.profile, input.command)?;
    let lim = input.lim;
    let knob = input.knob;
    let cmd = input.command;
    let unsupported =
        |why: String| GenError::Unsupported(format!("{m:?} on {}: {why}", input.profile.name));
    let mut also: Vec<String> = vec![];
    // Edits made after layout, on the realised world and call.
    let mut post: Vec<PostEdit> = vec![];
    match m {
        Mutation::MisalignTableAddress(t) => {
            ensure_used(&mut plan, t);
            plan.tables[t as usize].misalign = misalignment(lim.base_align, knob)
                .ok_or_else(|| unsupported("base alignment is 1".into()))?;
        }
        Mutation::MisalignTableStride(t) => {
            ensure_used(&mut plan, t);
            let delta = misalignment(lim.stride_align, knob)
                .ok_or_else(|| unsupported("stride alignment is 1".into()))?;
            let tp = &mut plan.tables[t as usize];
            let base = if tp.stride + delta > lim.max_stride {
                lim.min_stride()
            } else {
                tp.stride
            };
            if base + delta > lim.max_stride {
                return Err(unsupported(
                    "no misaligned stride fits under maxShaderGroupStride".into(),
                ));
            }
            tp.stride = base + delta;
        }
        Mutation::TableStrideAboveMax(t) => {
            ensure_used(&mut plan, t);
            plan.tables[t as usize].stride = round_up(lim.max_stride + 1, lim.stride_align)
                + (knob % 3) as u64 * lim.stride_align;
        }
        Mutation::RaygenSizeNotStride => {
            let tp = &mut plan.tables[Table::Raygen as usize];
            tp.size_override = Some(match knob % 3 {
                0 => tp.stride + 1,
                1 => tp.stride - 1,
                _ => tp.stride * 2,
            });
        }
        Mutation::TableBufferUsage(t) => {
            ensure_used(&mut plan, t);
            plan.tables[t as usize].separate = true;
            post.push(Box::new(move |w, _| {
                buffer_mut(w, &table_buffer(t))
                    .usage
                    .remove(BufferUsage::SHADER_BINDING_TABLE_BIT_KHR)
            }));
        }
        Mutation::TableBufferMemory(t) => {
            ensure_used(&mut plan, t);
            plan.tables[t as usize].separate = true;
            let mem = if knob % 2 == 0 {
                MemoryBinding::Unbound
            } else {
                MemoryBinding::Scattered
            };
            post.push(Box::new(move |w, _| {
                buffer_mut(w, &table_buffer(t)).memory = mem
            }));
        }
        Mutation::IndirectBufferUsage => {
            post.push(Box::new(|w, _| {
                buffer_mut(w, INDIRECT)
                    .usage
                    .remove(BufferUsage::INDIRECT_BUFFER_BIT)
            }));
        }
        Mutation::IndirectBufferMemory => {
            let mem = if knob % 2 == 0 {
                MemoryBinding::Unbound
            } else {
                MemoryBinding::Scattered
            };
            post.push(Box::new(move |w, _| buffer_mut(w, INDIRECT).memory = mem));
        }
        Mutation::MisalignIndirectAddress => {
            plan.indirect.misalign = [1, 3, 2][knob as usize % 3];
        }
        Mutation::IndirectCommandPastEnd => {
            // One byte past the end, the address at the last byte, the address just past the end.
            let k = [1u64, 11, 12][knob as usize % 3];
            plan.indirect.offset = plan.indirect.offset.max(4);
            plan.indirect.buffer_size_override = Some(plan.indirect.offset + 12 - k);
        }
        Mutation::DisableFeature(f) => {
            plan.device.features.remove(f);
        }
        Mutation::MotionPipelineWithoutFeature => {
            plan.flags
                .insert(PipelineCreate::RAY_TRACING_ALLOW_MOTION_BIT_NV);
            plan.device
                .extensions
                .insert("VK_NV_ray_tracing_motion_blur".into());
            if input.profile.has_feature("rayTracingMotionBlur") {
                plan.device.features.insert("rayTracingMotionBlur".into());
            }
            plan.device
                .features
                .remove("rayTracingMotionBlurPipelineTraceRaysIndirect");
        }
        Mutation::ForeignHandle => {
            ensure_launch(&mut plan);
            // Boundary: the raygen record, which every launch reads; otherwise a fresh reached miss record.
            if knob % 2 == 0 {
                plan.tables[Table::Raygen as usize].records[0] = HandleRef::Foreign(0);
            } else {
                let g = GroupIndex::of(&plan.groups)
                    .miss
                    .first()
                    .copied()
                    .unwrap_or(0);
                add_miss_ray(&mut plan, HandleRef::Foreign(g));
                keep_recursion(&mut plan);
            }
        }
        Mutation::RecursionTooDeep => {
            // Only traced rays deepen the recursion (callables add none), and closest-hit shaders
            // trace again only where a ray runs one: the depth is the one the launch reaches.
            if !plan.launch.traces() {
                let h = miss_handle(&mut plan);
                add_miss_ray(&mut plan, h);
            }
            ensure_launch(&mut plan);
            let (world, call) = realize(&plan, lim);
            let depth = model::semantics::recursion_depth(&world, &call).max(1);
            plan.max_recursion_depth = if knob % 2 == 0 { depth - 1 } else { 0 };
        }
        Mutation::NullMissAtRegionAddress => {
            // 03511 speaks of the handle at pMissShaderBindingTable->deviceAddress (record 0), whether
            // or not a ray misses: a zero group there, or (knob 1) no miss table at all.
            plan.flags
                .insert(PipelineCreate::RAY_TRACING_NO_NULL_MISS_SHADERS_BIT_KHR);
            // No miss table at all only where no ray is traced (a traced ray may miss, and would read
            // a miss record outside any region).
            if knob % 2 == 1 && !plan.launch.traces() {
                plan.tables[Table::Miss as usize].records.clear();
            } else {
                ensure_used(&mut plan, Table::Miss);
                plan.tables[Table::Miss as usize].records[0] = HandleRef::Zero;
            }
            keep_recursion(&mut plan);
        }
        Mutation::NullHitReached(kind) => {
            let (flag, geometry) = match kind {
                NullHit::AnyHit => (
                    PipelineCreate::RAY_TRACING_NO_NULL_ANY_HIT_SHADERS_BIT_KHR,
                    if knob % 2 == 0 {
                        GeometryKind::Triangles
                    } else {
                        GeometryKind::Aabbs
                    },
                ),
                NullHit::ClosestHit => (
                    PipelineCreate::RAY_TRACING_NO_NULL_CLOSEST_HIT_SHADERS_BIT_KHR,
                    if knob % 2 == 0 {
                        GeometryKind::Triangles
                    } else {
                        GeometryKind::Aabbs
                    },
                ),
                NullHit::Intersection => (
                    PipelineCreate::RAY_TRACING_NO_NULL_INTERSECTION_SHADERS_BIT_KHR,
                    GeometryKind::Aabbs,
                ),
            };
            // The other NO_NULL hit flags would make the zero record a second violation: they go.
            plan.flags.remove(
                PipelineCreate::RAY_TRACING_NO_NULL_ANY_HIT_SHADERS_BIT_KHR
                    | PipelineCreate::RAY_TRACING_NO_NULL_CLOSEST_HIT_SHADERS_BIT_KHR
                    | PipelineCreate::RAY_TRACING_NO_NULL_INTERSECTION_SHADERS_BIT_KHR,
            );
            plan.flags.insert(flag);
            // The pipeline can only be created with the flag if every hit group has the shader it names.
            for g in plan.groups.iter_mut() {
                match (kind, g) {
                    (
                        NullHit::AnyHit,
                        ShaderGroup::TrianglesHit { any_hit, .. }
                        | ShaderGroup::ProceduralHit { any_hit, .. },
                    ) => *any_hit = true,
                    (
                        NullHit::ClosestHit,
                        ShaderGroup::TrianglesHit { closest_hit, .. }
                        | ShaderGroup::ProceduralHit { closest_hit, .. },
                    ) => *closest_hit = true,
                    _ => {}
                }
            }
            add_hit_ray(&mut plan, geometry, HandleRef::Zero);
            keep_recursion(&mut plan);
        }
        Mutation::NullHitTableWithNoNullFlag(kind) => {
            // No ray may reach a hit record once the table is gone: rays that aim at geometry are dropped.
            plan.tables[Table::Hit as usize].records.clear();
            // (Any ray may reach a box's record: boxes may be enlarged without bound.)
            plan.launch.scene = Default::default();
            if kind == NullHit::ClosestHit {
                plan.flags
                    .insert(PipelineCreate::RAY_TRACING_NO_NULL_CLOSEST_HIT_SHADERS_BIT_KHR);
                for g in plan.groups.iter_mut() {
                    if let ShaderGroup::TrianglesHit { closest_hit, .. }
                    | ShaderGroup::ProceduralHit { closest_hit, .. } = g
                    {
                        *closest_hit = true;
                    }
                }
            } else {
                plan.flags
                    .insert(PipelineCreate::RAY_TRACING_NO_NULL_INTERSECTION_SHADERS_BIT_KHR);
            }
            // The other hit flag would now be violated too; it is not part of this case.
            let other = if kind == NullHit::ClosestHit {
                PipelineCreate::RAY_TRACING_NO_NULL_INTERSECTION_SHADERS_BIT_KHR
            } else {
                PipelineCreate::RAY_TRACING_NO_NULL_CLOSEST_HIT_SHADERS_BIT_KHR
            };
            plan.flags.remove(other);
            if !plan.launch.traces() && plan.launch.callables.is_empty() {
                plan.max_recursion_depth = plan.max_recursion_depth.min(lim.max_recursion as u32);
            }
        }
        Mutation::HitGroupMismatch(kind) => {
            let gi = GroupIndex::of(&plan.groups);
            let ch = plan
                .flags
                .contains(PipelineCreate::RAY_TRACING_NO_NULL_CLOSEST_HIT_SHADERS_BIT_KHR)
                || knob % 2 == 0;
            let ah = plan
                .flags
                .contains(PipelineCreate::RAY_TRACING_NO_NULL_ANY_HIT_SHADERS_BIT_KHR);
            let wrong = match kind {
                GeometryKind::Triangles => gi.procedural.first().copied(),
                GeometryKind::Aabbs => gi.triangles.first().copied(),
            };
            let g = match wrong {
                Some(g) => g,
                None => {
                    plan.groups.push(match kind {
                        GeometryKind::Triangles => ShaderGroup::ProceduralHit {
                            closest_hit: ch,
                            any_hit: ah,
                            any_hit_rule: Default::default(),
                            intersection: true,
                        },
                        GeometryKind::Aabbs => ShaderGroup::TrianglesHit {
                            closest_hit: ch,
                            any_hit: ah,
                            any_hit_rule: Default::default(),
                        },
                    });
                    plan.groups.len() as u32 - 1
                }
            };
            add_hit_ray(&mut plan, kind, HandleRef::Group(g));
            keep_recursion(&mut plan);
        }
        Mutation::DynamicStackSizeNotSet | Mutation::StaticStackSizeSet
            if cmd == CommandId::TraceRaysNv =>
        {
            // 09458 and 08608's stack size concern the KHR pipeline's stack-size state, which an NV
            // pipeline does not have (its create info takes no dynamic states).
            return Err(unsupported(
                "an NV pipeline has no stack-size state, dynamic or static".into(),
            ));
        }
        Mutation::DynamicStackSizeNotSet => {
            plan.dynamic_stack_size = true;
            plan.command_buffer.stack_size_set = false;
        }
        Mutation::StaticStackSizeSet => {
            plan.dynamic_stack_size = false;
            plan.command_buffer.stack_size_set = true;
        }
        Mutation::ProtectedResource => {
            plan.device.features.insert("protectedMemory".into());
            let t = Table::ALL[input.pick as usize % 4];
            ensure_used(&mut plan, t);
            plan.tables[t as usize].separate = true;
            post.push(Box::new(move |w, _| {
                buffer_mut(w, &table_buffer(t))
                    .flags
                    .insert(BufferCreate::PROTECTED_BIT)
            }));
        }
        Mutation::ProtectedCommandBuffer => {
            plan.device.features.insert("protectedMemory".into());
            let families = queue_families(input.profile);
            let q = families
                .iter()
                .copied()
                .filter(|q| q.contains(QueueFlags::PROTECTED_BIT))
                .max_by_key(|q| q.contains(QueueFlags::COMPUTE_BIT))
                .expect("checked by supported()");
            if !q.contains(QueueFlags::COMPUTE_BIT) {
                also.extend(registry_vuid(input.rules, cmd.vk_name(), "cmdpool"));
            }
            plan.command_buffer.pool_queue = q;
            plan.command_buffer.protected = true;
        }
        Mutation::NotRecording => {
            plan.command_buffer.lifecycle = [
                CommandBufferLifecycle::Executable,
                CommandBufferLifecycle::Initial,
                CommandBufferLifecycle::Invalid,
            ][knob as usize % 3];
            // Nothing is bound in a command buffer that was never begun: the pipeline rule fires too.
            if plan.command_buffer.lifecycle == CommandBufferLifecycle::Initial {
                also.extend(no_pipeline_vuids(&plan, input.rules, cmd.vk_name()));
            }
        }
        Mutation::PoolWithoutCompute => {
            let families: Vec<QueueFlags> = queue_families(input.profile)
                .into_iter()
                .filter(|q| !q.is_empty_set() && !q.contains(QueueFlags::COMPUTE_BIT))
                .collect();
            plan.command_buffer.pool_queue = families[input.pick as usize % families.len()];
            // Nothing can be bound at the ray tracing bind point in such a pool (binding a ray tracing
            // pipeline needs compute, VUID-vkCmdBindPipeline-pipelineBindPoint-02391, and so does the
            // stack size, VUID-vkCmdSetRayTracingPipelineStackSizeKHR-commandBuffer-cmdpool): the
            // pipeline rule fires too. As with no pipeline bound, a zero dimension reads no record, so
            // 03429 (handles from the bound pipeline) cannot apply.
            plan.command_buffer.pipeline_bound = false;
            plan.command_buffer.stack_size_set = false;
            plan.dims[(knob % 3) as usize] = 0;
            also.extend(no_pipeline_vuids(&plan, input.rules, cmd.vk_name()));
        }
        Mutation::InsideRenderPass => {
            if !plan
                .command_buffer
                .pool_queue
                .contains(QueueFlags::GRAPHICS_BIT)
            {
                plan.command_buffer.pool_queue = queue_families(input.profile)
                    .into_iter()
                    .find(|q| q.contains(QueueFlags::GRAPHICS_BIT | QueueFlags::COMPUTE_BIT))
                    .expect("checked by supported()");
            }
            plan.command_buffer.in_render_pass = true;
        }
        Mutation::InsideVideoCoding => {
            let video = QueueFlags::VIDEO_DECODE_BIT_KHR | QueueFlags::VIDEO_ENCODE_BIT_KHR;
            let q = queue_families(input.profile)
                .into_iter()
                .filter(|q| q.intersects(video))
                .max_by_key(|q| q.contains(QueueFlags::COMPUTE_BIT))
                .expect("checked by supported()");
            if !q.contains(QueueFlags::COMPUTE_BIT) {
                also.extend(registry_vuid(input.rules, cmd.vk_name(), "cmdpool"));
            }
            plan.command_buffer.pool_queue = q;
            plan.command_buffer.in_video_coding = true;
        }
        Mutation::NoPipelineBound | Mutation::NoPipelineBoundWithShaderObject => {
            if m == Mutation::NoPipelineBoundWithShaderObject {
                plan.device.features.insert("shaderObject".into());
            } else {
                plan.device.features.remove("shaderObject");
            }
            // With nothing bound no handle can have been queried from the bound pipeline; a launch
            // with a zero dimension reads no record, so 03429 cannot apply.
            plan.command_buffer.pipeline_bound = false;
            plan.command_buffer.stack_size_set = false;
            plan.dims[(knob % 3) as usize] = 0;
        }
        Mutation::DimensionAboveLimit(i) => {
            let over =
                lim.max_dim[i as usize] + 1 + (knob % 2) as u64 * lim.max_dim[i as usize] / 2;
            if over > u32::MAX as u64 {
                return Err(unsupported(format!(
                    "the limit of dimension {i} is at u32::MAX"
                )));
            }
            plan.dims = [1, 1, 1];
            plan.dims[i as usize] = over as u32;
            if let Some(max_inv) = lim.max_invocations {
                if over > max_inv {
                    // width × height × depth is then above maxRayDispatchInvocationCount too.
                    let scope = if cmd == CommandId::TraceRaysIndirect {
                        "VkTraceRaysIndirectCommandKHR"
                    } else {
                        cmd.vk_name()
                    };
                    also.extend(registry_vuid(input.rules, scope, "03641"));
                }
            }
        }
        Mutation::InvocationsAboveLimit => {
            let max_inv = lim
                .max_invocations
                .ok_or_else(|| unsupported("no maxRayDispatchInvocationCount".into()))?;
            let target = max_inv + 1 + (knob % 2) as u64 * max_inv;
            let mut dims = [1u64; 3];
            let mut product = 1u64;
            for (d, max) in dims.iter_mut().zip(lim.max_dim) {
                let want = target.div_ceil(product);
                *d = want.min(max).min(u32::MAX as u64).max(1);
                product = product.saturating_mul(*d);
            }
            if product <= max_inv {
                return Err(unsupported("the per-dimension limits keep the product within maxRayDispatchInvocationCount".into()));
            }
            plan.dims = [dims[0] as u32, dims[1] as u32, dims[2] as u32];
        }
        Mutation::RegionPastBufferEnd => {
            let t = Table::ALL[input.pick as usize % 4];
            ensure_used(&mut plan, t);
            let tp = &mut plan.tables[t as usize];
            tp.separate = true;
            // Offset at least the stride, so the shortened buffer still holds a stride (04632).
            tp.lead = round_up(tp.stride, lim.base_align);
            let n = tp.records.len() as u64;
            let size = match (t, tp.size_override) {
                (_, Some(s)) => s,
                (Table::Raygen, None) => tp.stride,
                _ => n * tp.stride + tp.size_extra,
            };
            // One byte past the end, the last byte of the region is past... the region starting at the last byte, just past the end.
            let k = match knob % 3 {
                0 => 1,
                1 => size.saturating_sub(1).max(1),
                _ => size,
            };
            tp.buffer_size_override = Some(tp.lead + size - k);
        }
        Mutation::StrideAboveBufferSize => {
            // One record in a buffer of its own, the region exactly the handle; raygen would also break
            // size == stride, so miss or callable.
            let t = if input.pick % 2 == 0 {
                Table::Miss
            } else {
                Table::Callable
            };
            match t {
                Table::Miss => {
                    let h = miss_handle(&mut plan);
                    for r in plan.launch.rays.iter_mut() {
                        r.miss_index = 0;
                    }
                    plan.tables[t as usize].records = vec![h];
                }
                _ => {
                    let gi = GroupIndex::of(&plan.groups);
                    let h = match gi.callable.first() {
                        Some(&g) => HandleRef::Group(g),
                        None => {
                            plan.launch.callables.clear();
                            HandleRef::Zero
                        }
                    };
                    for c in plan.launch.callables.iter_mut() {
                        *c = 0;
                    }
                    plan.tables[t as usize].records = vec![h];
                }
            }
            let tp = &mut plan.tables[t as usize];
            tp.separate = true;
            tp.lead = 0;
            tp.size_override = Some(lim.handle_size);
            // The smallest stride before layout, so the buffer is as small as the record.
            tp.stride = lim.min_stride();
            let (align, max_stride) = (lim.stride_align, lim.max_stride);
            let extra = (knob % 2) as u64 * align;
            let mut err = None;
            post.push(Box::new(move |w, c| {
                let b = buffer_mut(w, &table_buffer(t));
                let stride = round_up(b.size + 1, align) + extra;
                if let Some(Contents::ShaderRecords { stride: s, .. }) = b.contents.first_mut() {
                    *s = stride;
                }
                let region = match c {
                    Call::TraceRays(x) if t == Table::Miss => Some(&mut x.miss),
                    Call::TraceRays(x) => Some(&mut x.callable),
                    Call::TraceRaysIndirect(x) if t == Table::Miss => Some(&mut x.miss),
                    Call::TraceRaysIndirect(x) => Some(&mut x.callable),
                    Call::TraceRaysNv(_) => None,
                };
                if let Some(r) = region {
                    r.stride = stride;
                }
            }));
            if round_up(lim.min_stride() + 1, align) + extra > max_stride {
                err = Some(unsupported(
                    "a stride above the buffer size would exceed maxShaderGroupStride".into(),
                ));
            }
            if let Some(e) = err {
                return Err(e);
            }
        }
        Mutation::NvOffsetPastBuffer(t) => {
            ensure_used(&mut plan, t);
            plan.tables[t as usize].separate = true;
            let (ba, extra) = (lim.base_align, (knob % 2) as u64);
            post.push(Box::new(move |w, c| {
                let b = buffer_mut(w, &table_buffer(t));
                // The buffer's size made a multiple of the base alignment, the offset exactly there.
                b.size = round_up(b.size, ba);
                let offset = b.size + extra * ba;
                if let Some(Contents::ShaderRecords { offset: o, .. }) = b.contents.first_mut() {
                    *o = offset;
                }
                if let Call::TraceRaysNv(x) = c {
                    match t {
                        Table::Raygen => x.raygen.offset = offset,
                        Table::Miss => x.miss.offset = offset,
                        Table::Hit => x.hit.offset = offset,
                        Table::Callable => x.callable.offset = offset,
                    }
                }
            }));
        }
        // Resource mutations are handled at the top of this function.
        Mutation::Resource(_) => unreachable!("resource mutations return early"),
        Mutation::NvInvalidBuffer(t) => {
            ensure_used(&mut plan, t);
            let none = t == Table::Raygen && knob % 2 == 0;
            post.push(Box::new(move |_, c| {
                if let Call::TraceRaysNv(x) = c {
                    let table = match t {
                        Table::Raygen => &mut x.raygen,
                        Table::Miss => &mut x.miss,
                        Table::Hit => &mut x.hit,
                        Table::Callable => &mut x.callable,
                    };
                    table.buffer = if none {
                        None
                    } else {
                        Some("destroyed-buffer".into())
                    };
                }
            }));
        }
    }
    let (mut world, mut call) = realize(&plan, lim);
    for p in post {
        p(&mut world, &mut call);
    }
    also.retain(|v| v != input.vuid);
    also.sort();
    also.dedup();
    Ok(Mutated { world, call, also })
}
