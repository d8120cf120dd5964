//! Vulkan plumbing: the instance with the validation layer and the messenger that collects its
//! messages, devices with exactly a case's extensions and features (and the layer's record of the
//! modules it passed), host-visible and sparse buffer memory, one-shot command buffers, and the
//! feature and property structure layouts generated from vk.xml; and the process's one turn in Vulkan
//! (the layer's state is not safe for two threads making and using devices at once).

pub(crate) mod commands;
pub(crate) mod descriptors;
pub(crate) mod device;
mod instance;
pub(crate) mod layout;
pub(crate) mod memory;
pub(crate) mod structs;
#[rustfmt::skip] // generated from vk.xml by vk-registry (see ARCHITECTURE.md); the drift test compares it byte for byte
#[allow(dead_code)] // every structure of vk.xml the harness may chain is listed; not every one is read
pub(crate) mod tables;
pub(crate) mod turn;
pub(crate) mod validated;

pub(crate) use device::VkDevice;
pub use instance::{
    select_layer, validation_layer, Driver, LayerInfo, LayerMessage, VALIDATION_LAYER,
};
pub(crate) use instance::{Collector, VkInstance};

/// A lavapipe device with no extension or feature enabled, without the layer: for unit tests of the
/// plumbing.
#[cfg(test)]
pub(crate) fn plain_lavapipe_device() -> VkDevice {
    lavapipe_device(&[], &[])
}

/// A lavapipe device with `extensions` and `features` enabled, without the layer: for unit tests.
#[cfg(test)]
pub(crate) fn lavapipe_device(extensions: &[&str], features: &[&str]) -> VkDevice {
    let inst = std::sync::Arc::new(VkInstance::new(Driver::Lavapipe, false).expect("lavapipe"));
    let names = |n: &[&str]| n.iter().map(|s| s.to_string()).collect();
    VkDevice::new(inst, &names(extensions), &names(features), None).expect("a device")
}
