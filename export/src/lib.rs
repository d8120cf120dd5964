//! Standalone C reproducers of rtconf cases, for bug reports: a case's call plan
//! ([`harness::plan::CallPlan`], the plan the harness itself realises) written as one C file that
//! needs only the Vulkan headers and loader (`cc repro.c -lvulkan -o repro`). The program makes every
//! buffer (with its bytes), shader binding table, acceleration structure and pipeline of the case
//! (the SPIR-V embedded as words), records the case's commands in the plan's order, prints what the
//! model expects and what the driver and the validation layer did, and exits 0 when they agree.

mod build;
mod c;
mod check;
mod records;
mod trace;

use c::Emitter;
use harness::plan::{CallPlan, DevicePlan, PlanBody};

/// The command that builds an exported program, run in its folder.
pub const BUILD_COMMAND: &str = "cc repro.c -lvulkan -o repro";

/// What the model says of the case, written into the program to compare with.
#[derive(Debug, Clone, Default)]
pub struct Expectation {
    /// The VUIDs the model says the call violates, sorted.
    pub model_vuids: Vec<String>,
    /// Each violation as `VUID at path: problem`, for the reader.
    pub violations: Vec<String>,
    /// What the model allows each ray of a valid launch (trace cases run as valid and read back).
    pub launch: Option<model::semantics::ExpectedLaunch>,
    /// A build case run as valid: the harness's traced check of it and what the model allows each
    /// of the check's rays.
    pub build_check: Option<BuildCheckExpectation>,
    /// How the case came about (its intent, seed, file), for the program's header.
    pub about: Vec<String>,
}

/// The traced check of a valid build (`harness::accel_check`) as the program repeats it: the case's
/// first info built directly with the ranges the model reads from memory, the check's rays traced at
/// the result with ray query, and what the model allows each ray (`model::accel::check::BuildCheck`).
#[derive(Debug, Clone)]
pub struct BuildCheckExpectation {
    pub plan: harness::plan::check::CheckPlan,
    /// One per ray of `plan`, in its order.
    pub allowed: Vec<model::tracer::AllowedOutcomes>,
}

/// An exported program.
#[derive(Debug, Clone)]
pub struct Program {
    pub source: String,
    pub build_command: &'static str,
}

/// Why a case cannot be exported (yet): the parts of a plan the C writer does not write.
#[derive(Debug, Clone, thiserror::Error)]
#[error("{case} cannot be exported as C: {why}")]
pub struct NotExportable {
    pub case: String,
    pub why: String,
}

const RUNTIME: &str = include_str!("runtime.c");

/// Writes a case's plan as a C program; see the module documentation.
pub fn export(plan: &CallPlan, expect: &Expectation) -> Result<Program, NotExportable> {
    let refuse = |why: &str| NotExportable {
        case: plan.case.clone(),
        why: why.into(),
    };
    if !plan.device.unknown.is_empty() {
        return Err(refuse(&format!(
            "no Vulkan structure holds feature(s) {}",
            plan.device.unknown.join(", ")
        )));
    }
    if plan.device.pool_family.is_some() {
        return Err(refuse(
            "its command pool is of a queue family without compute, and the C writer creates a device with the compute family's queue only",
        ));
    }
    let mut e = Emitter::default();
    header(&mut e, plan, expect);
    e.raw(RUNTIME);
    match &plan.body {
        PlanBody::Trace(t) => trace::emit(&mut e, plan, t, expect).map_err(|w| refuse(&w))?,
        PlanBody::Build(b) => build::emit(&mut e, plan, b, expect).map_err(|w| refuse(&w))?,
    }
    Ok(Program {
        source: e.finish(),
        build_command: BUILD_COMMAND,
    })
}

fn header(e: &mut Emitter, plan: &CallPlan, expect: &Expectation) {
    e.line("/*");
    e.line(&format!(
        " * rtconf reproducer: {} ({})",
        c::comment_safe(&plan.case),
        plan.command.vk_name()
    ));
    for a in &expect.about {
        e.line(&format!(" * {}", c::comment_safe(a)));
    }
    e.line(" *");
    e.line(&format!(" * Build: {BUILD_COMMAND}"));
    e.line(" * Run:   ./repro   (VK_DRIVER_FILES=/path/to/icd.json selects the driver)");
    e.line(" *");
    e.line(" * It makes the case's objects and records its commands as rtconf's harness does, under the");
    e.line(" * Khronos validation layer, and prints what the model expects, the layer's messages in full,");
    e.line(" * and (for a launch run for real) each launch ID's record judged against what the model allows");
    e.line(" * its ray. Exit status: 0 when the driver and the layer do what the model expects, 1 when they");
    e.line(" * do not (the device lost included), 2 when it cannot run.");
    e.line(" *");
    e.line(" * The call sequence:");
    for l in plan.describe() {
        e.line(&format!(" *   {}", c::comment_safe(&l)));
    }
    e.line(" */");
}

/// The device: its extensions, its features chained (`extra` names what the harness adds for a build's
/// traced check: ray query where the device has it, else a ray tracing pipeline).
pub(crate) fn emit_device(e: &mut Emitter, d: &DevicePlan, check_extras: bool) {
    let exts: Vec<String> = d.extensions.iter().map(|x| c::string(x)).collect();
    e.line(&format!(
        "const char *extensions[{}] = {{{}}};",
        exts.len() + 1,
        exts.join(", ")
    ));
    e.line(&format!("uint32_t extension_count = {};", exts.len()));
    e.line("VkPhysicalDeviceFeatures core;");
    e.line("memset(&core, 0, sizeof core);");
    for m in &d.core {
        e.line(&format!("core.{m} = VK_TRUE;"));
    }
    let mut head = "NULL".to_string();
    for (i, s) in d.chain.iter().enumerate() {
        e.line(&format!(
            "{} features{i} = {{{}, {head}}};",
            s.name, s.s_type_name
        ));
        for m in &s.members {
            e.line(&format!("features{i}.{m} = VK_TRUE;"));
        }
        head = format!("&features{i}");
    }
    e.line(&format!("void *feature_chain = {head};"));
    if check_extras {
        let has = |x: &str| d.extensions.iter().any(|e| e == x);
        let has_feature = |f: &str| {
            d.features
                .iter()
                .any(|x| x == f || x.ends_with(&format!("::{f}")))
        };
        e.line("/* The harness's device for a build also has what its traced check of the build needs: ray");
        e.line(" * query where the device has it, else a ray tracing pipeline. */");
        e.line("VkPhysicalDeviceRayQueryFeaturesKHR check_query = {VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_QUERY_FEATURES_KHR};");
        e.line("VkPhysicalDeviceRayTracingPipelineFeaturesKHR check_pipeline = {VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_FEATURES_KHR};");
        e.line("/* RTCONF_REPRO_CHECK=pipeline asks for the pipeline where ray query exists too (as `rtconf replay --check pipeline`). */");
        e.line("const char *check_asked = getenv(\"RTCONF_REPRO_CHECK\");");
        e.line("int check_by_query = 0, check_by_pipeline = 0;");
        e.line("if (!(check_asked && strcmp(check_asked, \"pipeline\") == 0) && has_extension(\"VK_KHR_ray_query\")) {");
        e.line("    check_by_query = 1;");
        if !has("VK_KHR_ray_query") {
            e.line("    extensions[extension_count++] = \"VK_KHR_ray_query\";");
        }
        if !has_feature("rayQuery") {
            e.line("    check_query.rayQuery = VK_TRUE;");
            e.line("    check_query.pNext = feature_chain;");
            e.line("    feature_chain = &check_query;");
        }
        e.line("} else if (has_extension(\"VK_KHR_ray_tracing_pipeline\")) {");
        e.line("    check_by_pipeline = 1;");
        if !has("VK_KHR_ray_tracing_pipeline") {
            e.line("    extensions[extension_count++] = \"VK_KHR_ray_tracing_pipeline\";");
        }
        if !has_feature("rayTracingPipeline") {
            e.line("    check_pipeline.rayTracingPipeline = VK_TRUE;");
            e.line("    check_pipeline.pNext = feature_chain;");
            e.line("    feature_chain = &check_pipeline;");
        }
        e.line("}");
        e.line("(void)check_query;");
        e.line("(void)check_pipeline;");
        e.line("(void)check_by_query;");
        e.line("(void)check_by_pipeline;");
    }
    let bda = d
        .features
        .iter()
        .any(|f| f == "bufferDeviceAddress" || f.ends_with("::bufferDeviceAddress"));
    e.line(&format!(
        "buffer_device_address = {};",
        if bda { 1 } else { 0 }
    ));
    e.line("make_device(extensions, extension_count, feature_chain, &core);");
    e.line("step(\"vkCreateDevice with the case's extensions and features\");");
}

/// Prints the model's expectation at the start of `main`.
pub(crate) fn emit_expectation(e: &mut Emitter, plan: &CallPlan, expect: &Expectation) {
    e.line(&format!(
        "printf(\"case:    %s (%s)\\n\", {}, {});",
        c::string(&plan.case),
        c::string(plan.command.vk_name())
    ));
    if expect.model_vuids.is_empty() {
        e.line("printf(\"model:   valid\\n\");");
    } else {
        e.line(&format!(
            "printf(\"model:   %s\\n\", {});",
            c::string(&expect.model_vuids.join(", "))
        ));
    }
    for v in &expect.violations {
        e.line(&format!("printf(\"         %s\\n\", {});", c::string(v)));
    }
    let vuids: Vec<String> = expect.model_vuids.iter().map(|v| c::string(v)).collect();
    e.line(&format!(
        "static const char *const model_vuids[{}] = {{{}}};",
        vuids.len().max(1),
        if vuids.is_empty() {
            "\"\"".to_string()
        } else {
            vuids.join(", ")
        }
    ));
    e.line(&format!("const int model_vuid_count = {};", vuids.len()));
}
