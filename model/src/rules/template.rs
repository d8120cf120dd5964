//! The template compiler: turns VUID texts of the common shapes ("`X` must be a multiple of `Y`",
//! "the buffer from which `A` was queried must have been created with the `B` usage flag", the
//! implicit `-recording`/`-cmdpool`/`-renderpass`/… rules) into [`Predicate`]s by resolving the quoted
//! parameter paths against the call and the quoted limits against the profile. One compiler for every
//! command: the command-buffer state and feature shapes give the same predicate for a trace call and a
//! build; the build command's array shapes (`Each element of pIndirectStrides …`) give its own.
//! No rule-specific code.

use super::predicate::{Operand, Predicate, StatePredicate};
use crate::accel::rules::AccelPredicate;
use crate::call::{Call, Param, Table};
use crate::command::CommandId;
use crate::flags::{BufferUsage, PipelineCreate, QueueFlags};
use regex::Regex;
use std::sync::OnceLock;

/// Strips the markup residue some registry versions leave (`pname:`, `sname:`) and backticks.
fn clean(s: &str) -> String {
    s.replace("pname:", "")
        .replace("sname:", "")
        .replace("ename:", "")
        .replace("flink:", "")
        .replace('`', "")
}

/// A limit operand: `Struct::member`, `Struct::member[i]`, a number, or a product with `{times}`/`×`.
fn operand(text: &str) -> Option<Operand> {
    let t = clean(text);
    let t = t.trim().trim_end_matches('.');
    let parts: Vec<&str> = t
        .split('×')
        .flat_map(|p| p.split("{times}"))
        .map(str::trim)
        .collect();
    if parts.len() > 1 {
        return parts
            .into_iter()
            .map(operand)
            .collect::<Option<Vec<_>>>()
            .map(Operand::Product);
    }
    if let Ok(n) = t.parse::<u64>() {
        return Some(Operand::Const(n));
    }
    static LIMIT: OnceLock<Regex> = OnceLock::new();
    let re =
        LIMIT.get_or_init(|| Regex::new(r"^(Vk[A-Za-z0-9]+)::([a-zA-Z0-9]+)(\[\d\])?$").unwrap());
    let c = re.captures(t)?;
    Some(Operand::Limit(format!(
        "{}::{}{}",
        &c[1],
        &c[2],
        c.get(3).map_or("", |m| m.as_str())
    )))
}

fn param(command: &str, text: &str) -> Option<Param> {
    Call::resolve_path(command, &clean(text))
}

fn flag_usage(name: &str) -> Option<BufferUsage> {
    BufferUsage::from_name(&clean(name))
}

fn flag_pipeline(name: &str) -> Option<PipelineCreate> {
    PipelineCreate::from_name(clean(name).trim_end_matches(','))
}

/// The NV buffer parameter (`missShaderBindingTableBuffer`) as the table's address parameter.
fn nv_buffer_param(command: &str, text: &str) -> Option<Param> {
    if command != "vkCmdTraceRaysNV" {
        return None;
    }
    let t = clean(text);
    Table::ALL
        .into_iter()
        .find(|tb| t == format!("{}TableBuffer", tb.nv_stem()))
        .map(Param::TableAddress)
}

/// Some(()) for the build command, whose array parameters the build shapes name.
fn build_only(command: &str) -> Option<()> {
    (command == CommandId::BuildAccelerationStructuresIndirect.vk_name()).then_some(())
}

/// What a shape makes of a text it matches, for a command (None: the quoted names do not resolve).
type Builder = fn(&str, &regex::Captures) -> Option<Predicate>;

type Shape = (&'static str, Builder);

/// Every text shape the compiler knows, in the order they are tried.
fn shapes() -> &'static [(Regex, Builder)] {
    static SHAPES: OnceLock<Vec<(Regex, Builder)>> = OnceLock::new();
    SHAPES.get_or_init(|| {
        let table: Vec<Shape> = vec![
            (r"^(?P<p>\S+) must be a multiple of (?P<v>.+)$", |c, m| {
                Some(Predicate::MultipleOf(param(c, &m["p"])?, operand(&m["v"])?))
            }),
            (r"^(?P<p>\S+) must be less than or equal to the size of (?P<b>\S+)$", |c, m| {
                let p = param(c, &m["p"])?;
                nv_buffer_param(c, &m["b"])?;
                Some(Predicate::AtMost(p, Operand::SizeOfBufferOf(p)))
            }),
            (r"^(?P<p>\S+) must be less than the size of (?P<b>\S+)$", |c, m| {
                let p = param(c, &m["p"])?;
                nv_buffer_param(c, &m["b"])?;
                Some(Predicate::LessThan(p, Operand::SizeOfBufferOf(p)))
            }),
            (r"^(?P<p>\S+) must be less than or equal to (?P<v>.+)$", |c, m| {
                Some(Predicate::AtMost(param(c, &m["p"])?, operand(&m["v"])?))
            }),
            (r"^The (?P<a>\S+) member of (?P<r>\S+) must be equal to its (?P<b>\S+) member$", |c, m| {
                let r = clean(&m["r"]);
                let a = param(c, &format!("{r}->{}", clean(&m["a"])))?;
                let b = param(c, &format!("{r}->{}", clean(&m["b"])))?;
                Some(Predicate::Equal(a, Operand::Param(b)))
            }),
            (r"^If the (?:currently )?bound ray tracing pipeline was created with (?:`?flags`? that included )?(?P<f>\S+),? (?P<p>\S+) must not be zero$", |c, m| {
                Some(Predicate::NonZeroIfPipelineFlag(param(c, &m["p"])?, flag_pipeline(&m["f"])?))
            }),
            (r"^If the bound ray tracing pipeline was created with (?P<f>\S+),? (?:`?Vk[A-Za-z]+`?::)?(?P<feat>\S+) feature must be enabled$", |_, m| {
                Some(Predicate::FeatureEnabledIfPipelineFlag(flag_pipeline(&m["f"])?, clean(&m["feat"])))
            }),
            (r"^The (?:`?VkPhysicalDevice[A-Za-z0-9]+`?::)?(?P<f>\S+) feature must be enabled$", |_, m| Some(Predicate::State(StatePredicate::FeatureEnabled(clean(&m["f"]))))),
            (r"^The buffer from which (?:the )?(?P<p>\S+) (?:is|was) queried must have been created with the (?P<u>\S+) (?:usage flag|bit set)$", |c, m| {
                Some(Predicate::BufferUsage(param(c, &m["p"])?, flag_usage(&m["u"])?))
            }),
            (r"^If the buffer from which (?P<p>\S+) was queried is non-sparse then it must be bound completely and contiguously to a single `?VkDeviceMemory`? object$", |c, m| {
                Some(Predicate::BoundContiguously(param(c, &m["p"])?))
            }),
            (r"^If (?P<b>\S+) is non-sparse then it must be bound completely and contiguously to a single `?VkDeviceMemory`? object$", |c, m| {
                Some(Predicate::BoundContiguously(nv_buffer_param(c, &m["b"])?))
            }),
            (r"^All device addresses between (?P<p>\S+) and (?P<q>\S+) \+ `?sizeof`?\((?P<s>[^)]+)\) - 1 must be in the buffer device address range of the same buffer$", |c, m| {
                let p = param(c, &m["p"])?;
                let size = match clean(&m["s"]).as_str() {
                    "VkTraceRaysIndirectCommandKHR" => 12,
                    "VkTraceRaysIndirectCommand2KHR" => 104,
                    _ => return None,
                };
                Some(Predicate::RangeInOneBuffer(p, Operand::Const(size)))
            }),
            (r"^If `?size`? is not zero, all addresses between `?deviceAddress`? and `?deviceAddress`? \+ `?size`? - 1 must be in the buffer device address range of the same buffer$", |_, _| {
                Some(Predicate::RegionInOneBuffer)
            }),
            (r"^If `?size`? is not zero, `?stride`? must be less than or equal to the size of the buffer from which `?deviceAddress`? was queried$", |_, _| {
                Some(Predicate::RegionStrideWithinBuffer)
            }),
            (r"^`?commandBuffer`? must not be a protected command buffer$", |_, _| Some(Predicate::State(StatePredicate::NotProtectedCommandBuffer))),
            (r"^`?commandBuffer`? must be in the recording state$", |_, _| Some(Predicate::State(StatePredicate::Recording))),
            (r"^The `?VkCommandPool`? that `?commandBuffer`? was allocated from must support (?P<q>.+) operations$", |_, m| {
                let mut q = QueueFlags::empty();
                for w in m["q"].split(|c: char| c == ',' || c.is_whitespace()).filter(|w| !w.is_empty() && *w != "or") {
                    q.insert(match w {
                        "graphics" | "VK_QUEUE_GRAPHICS_BIT" => QueueFlags::GRAPHICS_BIT,
                        "compute" | "VK_QUEUE_COMPUTE_BIT" => QueueFlags::COMPUTE_BIT,
                        "transfer" | "VK_QUEUE_TRANSFER_BIT" => QueueFlags::TRANSFER_BIT,
                        _ => return None,
                    });
                }
                Some(Predicate::State(StatePredicate::PoolSupports(q)))
            }),
            (r"^This command must only be called outside of a render pass instance$", |_, _| Some(Predicate::State(StatePredicate::OutsideRenderPass))),
            (r"^This command must only be called outside of a video coding scope$", |_, _| Some(Predicate::State(StatePredicate::OutsideVideoCoding))),
            (r"^This command must not be called between suspended render pass instances$", |_, _| {
                Some(Predicate::State(StatePredicate::NotBetweenSuspendedRenderPasses))
            }),
            (r"^Each element of (?P<p>pIndirectDeviceAddresses|pIndirectStrides) must be a multiple of (?P<n>\d+)$", |c, m| {
                build_only(c)?;
                let n = m["n"].parse().ok()?;
                Some(Predicate::Accel(if &m["p"] == "pIndirectStrides" {
                    AccelPredicate::IndirectStrideMultipleOf(n)
                } else {
                    AccelPredicate::IndirectAddressMultipleOf(n)
                }))
            }),
            (r"^infoCount must be greater than 0$", |c, _| {
                build_only(c)?;
                Some(Predicate::Accel(AccelPredicate::InfoCountPositive))
            }),
            (r"^(?P<so>If the `?shaderObject`? feature is not enabled, )?[Aa] valid pipeline must be bound to the pipeline bind point used by this command$", |_, m| {
                Some(if m.name("so").is_some() {
                    Predicate::PipelineBoundWhenShaderObject(false)
                } else {
                    Predicate::PipelineBound
                })
            }),
            (r"^If (?P<b>\S+) is not VK_NULL_HANDLE, (?P<b2>\S+) must be a valid `?VkBuffer`? handle$", |c, m| {
                match nv_buffer_param(c, &m["b"])? {
                    Param::TableAddress(t) => Some(Predicate::ValidBufferHandle(t)),
                    _ => None,
                }
            }),
            (r"^(?P<b>\S+) must be a valid `?VkBuffer`? handle$", |c, m| match nv_buffer_param(c, &m["b"])? {
                Param::TableAddress(t) => Some(Predicate::ValidBufferHandle(t)),
                _ => None,
            }),
        ];
        table.into_iter().map(|(re, f)| (Regex::new(re).expect("template regexes are valid"), f)).collect()
    })
}

/// Structure-scoped texts of `VkTraceRaysIndirectCommandKHR`: the dimension fields are read from the
/// memory image rather than from call parameters.
fn indirect_command_shape(text: &str) -> Option<Predicate> {
    static DIM: OnceLock<Regex> = OnceLock::new();
    static PRODUCT: OnceLock<Regex> = OnceLock::new();
    let t = clean(text);
    let dim = DIM.get_or_init(|| {
        Regex::new(r"^(width|height|depth) must be less than or equal to (.+)$").unwrap()
    });
    if let Some(c) = dim.captures(&t) {
        let i = ["width", "height", "depth"]
            .iter()
            .position(|d| *d == &c[1])? as u8;
        return Some(Predicate::LaunchDimensionAtMost(i, operand(&c[2])?));
    }
    let product = PRODUCT.get_or_init(|| {
        Regex::new(r"^width (?:\{times\}|×) height (?:\{times\}|×) depth must be less than or equal to (.+)$").unwrap()
    });
    let c = product.captures(&t)?;
    Some(Predicate::LaunchInvocationsAtMost(operand(&c[1])?))
}

/// Compiles one VUID's normalised text for `command` (or a structure scope), or None when no template
/// shape fits.
pub fn compile(scope: &str, command: &str, text: &str) -> Option<Predicate> {
    let text = text.trim().trim_end_matches('.');
    if scope == "VkTraceRaysIndirectCommandKHR" {
        return indirect_command_shape(text);
    }
    // The product of the launch dimensions reads the same for direct calls and indirect commands.
    if let Some(p @ Predicate::LaunchInvocationsAtMost(_)) = indirect_command_shape(text) {
        return Some(p);
    }
    let cleaned = clean(text);
    for (re, build) in shapes() {
        // Try the text as written (backticks help delimit) and cleaned of markup.
        for candidate in [text, cleaned.as_str()] {
            if let Some(m) = re.captures(candidate) {
                if let Some(p) = build(command, &m) {
                    return Some(p);
                }
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(scope: &str, text: &str, expect: Option<Predicate>) {
        assert_eq!(compile(scope, scope, text), expect, "text: {text}");
    }

    #[test]
    fn multiple_of_a_limit_and_of_a_constant() {
        check(
            "vkCmdTraceRaysIndirectKHR",
            "pname:pMissShaderBindingTable->stride must be a multiple of `VkPhysicalDeviceRayTracingPipelinePropertiesKHR`::`shaderGroupHandleAlignment`",
            Some(Predicate::MultipleOf(
                Param::TableStride(Table::Miss),
                Operand::Limit("VkPhysicalDeviceRayTracingPipelinePropertiesKHR::shaderGroupHandleAlignment".into()),
            )),
        );
        check(
            "vkCmdTraceRaysIndirectKHR",
            "`indirectDeviceAddress` must be a multiple of `4`",
            Some(Predicate::MultipleOf(
                Param::IndirectAddress,
                Operand::Const(4),
            )),
        );
    }

    #[test]
    fn nv_offsets_against_buffer_sizes_and_limits() {
        check(
            "vkCmdTraceRaysNV",
            "`hitShaderBindingOffset` must be less than the size of `hitShaderBindingTableBuffer`",
            Some(Predicate::LessThan(
                Param::TableAddress(Table::Hit),
                Operand::SizeOfBufferOf(Param::TableAddress(Table::Hit)),
            )),
        );
        check(
            "vkCmdTraceRaysNV",
            "`width` must be less than or equal to `VkPhysicalDeviceLimits`::`maxComputeWorkGroupCount`[0]",
            Some(Predicate::AtMost(Param::Dimension(0), Operand::Limit("VkPhysicalDeviceLimits::maxComputeWorkGroupCount[0]".into()))),
        );
    }

    #[test]
    fn usage_flags_features_and_implicit_rules() {
        check(
            "vkCmdTraceRaysIndirectKHR",
            "The buffer from which `indirectDeviceAddress` was queried must have been created with the `VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT` bit set",
            Some(Predicate::BufferUsage(Param::IndirectAddress, BufferUsage::INDIRECT_BUFFER_BIT)),
        );
        check(
            "vkCmdTraceRaysIndirectKHR",
            "The pname:rayTracingPipelineTraceRaysIndirect feature must be enabled",
            Some(Predicate::State(StatePredicate::FeatureEnabled(
                "rayTracingPipelineTraceRaysIndirect".into(),
            ))),
        );
        check(
            "vkCmdTraceRaysIndirectKHR",
            "The `VkCommandPool` that `commandBuffer` was allocated from must support compute operations",
            Some(Predicate::State(StatePredicate::PoolSupports(QueueFlags::COMPUTE_BIT))),
        );
        check(
            "vkCmdTraceRaysKHR",
            "This command must only be called outside of a render pass instance",
            Some(Predicate::State(StatePredicate::OutsideRenderPass)),
        );
    }

    #[test]
    fn indirect_command_products_of_limits() {
        check(
            "VkTraceRaysIndirectCommandKHR",
            "`width` must be less than or equal to `VkPhysicalDeviceLimits`::`maxComputeWorkGroupCount`[0] {times} `VkPhysicalDeviceLimits`::`maxComputeWorkGroupSize`[0]",
            Some(Predicate::LaunchDimensionAtMost(
                0,
                Operand::Product(vec![
                    Operand::Limit("VkPhysicalDeviceLimits::maxComputeWorkGroupCount[0]".into()),
                    Operand::Limit("VkPhysicalDeviceLimits::maxComputeWorkGroupSize[0]".into()),
                ]),
            )),
        );
    }

    #[test]
    fn unknown_shapes_and_unknown_paths_do_not_compile() {
        check(
            "vkCmdTraceRaysIndirectKHR",
            "Any shader invocation executed by this command must terminate",
            None,
        );
        check(
            "vkCmdTraceRaysIndirectKHR",
            "`notAParameter` must be a multiple of `4`",
            None,
        );
    }
}
