//! Written reasons for the VUIDs the model does not execute, and the classifier that files the
//! resource-access rules shared with draw/dispatch as pending until their model exists.

use super::Status;
use vk_registry::vuid::VuidRecord;

/// A resource-access rule the resource world (`crate::resources`) does not model yet.
pub const RESOURCE_PENDING: &str =
    "resource-access rule shared with draw/dispatch (samplers, views, descriptors, push constants, formats) that the resource world does not model yet";

const TERMINATE: &str =
    "termination of shader code is undecidable in general; the suite's shaders are straight-line \
     and always terminate, so no case the suite can express violates it";

const HANDLE_OR_POINTER: &str = "the case format always passes live handles and valid pointers (a region is a value, \
     the command buffer is the one being recorded); a dangling handle or pointer cannot be expressed, and passing one \
     to the driver is undefined behaviour the layer's object tracker reports before any rule";

const COMMON_PARENT: &str =
    "a case lives on one VkDevice; objects of two devices cannot be expressed";

/// Words that mark a rule as one of the resource-access rules every dispatching command shares.
const RESOURCE_WORDS: &[&str] = &[
    "VkSampler",
    "VkImageView",
    "VkBufferView",
    "image view",
    "descriptor",
    "push constant",
    "OpType",
    "OpImage",
    "QCOM",
    "SampledType",
    "format features",
    "Tensor",
    "tile",
    "robustBufferAccess",
    "uniform buffer",
    "storage buffer",
    "uniformBuffers",
    "storageBuffers",
    "VkImage",
    "VkShaderEXT",
    "sampler",
    "pipeline layout",
    "VkPipelineLayout",
    "feedback loop",
    "attachment",
    "maintenance4",
];

/// The status and reason of a row no template or hand rule executes.
pub fn classify(r: &VuidRecord) -> (Status, String) {
    let tag = r.tag.as_str();
    if tag == "07288" {
        return (Status::NotExecutable, TERMINATE.into());
    }
    if tag == "commonparent" {
        return (Status::NotExecutable, COMMON_PARENT.into());
    }
    if tag == "parameter" {
        return (Status::NotExecutable, HANDLE_OR_POINTER.into());
    }
    if RESOURCE_WORDS.iter().any(|w| r.text.contains(w)) {
        return (Status::Pending, RESOURCE_PENDING.into());
    }
    (
        Status::Pending,
        "no template shape fits this text and no hand rule is written yet".into(),
    )
}
