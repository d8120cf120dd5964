/* ---- What every rtconf reproducer shares: the instance with the validation layer and a messenger
 * that collects its messages (and, while asked, makes the layer drop the call), the device, buffers
 * placed at aligned device addresses in host-visible memory, one-shot command buffers. The case's
 * own objects and commands follow in main(). ---- */
#include <vulkan/vulkan.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>

/* Helpers a case does not use are not warned about. */
#if defined(__GNUC__)
#define HELPER static __attribute__((unused))
#else
#define HELPER static
#endif

#define MAX_MESSAGES 512
struct message {
    char severity[8];
    char id[192];
    char *text;
};
static struct message messages[MAX_MESSAGES];
static int message_count;
/* While set, the messenger returns VK_TRUE: the layer drops the call instead of passing it on. */
static int drop_calls;

static VkInstance instance;
static VkDebugUtilsMessengerEXT messenger;
static VkPhysicalDevice physical;
static VkPhysicalDeviceProperties device_properties;
static VkPhysicalDeviceMemoryProperties memory_properties;
static VkDevice device;
static VkQueue queue;
static uint32_t queue_family;
static VkCommandPool pool;
static VkCommandBuffer primary, secondary;
static VkFence fence;
static int buffer_device_address; /* the case enables bufferDeviceAddress */

HELPER void fail(const char *what, VkResult result) {
    fprintf(stderr, "rtconf reproducer: %s failed: VkResult %d\n", what, (int)result);
    if (result == VK_ERROR_DEVICE_LOST) {
        /* The driver lost the device on what the case gives it: the driver's failure, not the program's. */
        printf("verdict: the driver lost the device (VK_ERROR_DEVICE_LOST) in %s\n", what);
        exit(1);
    }
    exit(2);
}

#define CHECK(call)                                  \
    do {                                             \
        VkResult check_result_ = (call);             \
        if (check_result_ != VK_SUCCESS)             \
            fail(#call, check_result_);              \
    } while (0)

HELPER void step(const char *what) { printf("  %s\n", what); }

static VKAPI_ATTR VkBool32 VKAPI_CALL on_message(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                 VkDebugUtilsMessageTypeFlagsEXT types,
                                                 const VkDebugUtilsMessengerCallbackDataEXT *data,
                                                 void *user) {
    (void)types;
    (void)user;
    if (message_count < MAX_MESSAGES) {
        struct message *m = &messages[message_count++];
        const char *s = (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT)     ? "error"
                        : (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT) ? "warning"
                        : (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_INFO_BIT_EXT)    ? "info"
                                                                                        : "verbose";
        snprintf(m->severity, sizeof m->severity, "%s", s);
        snprintf(m->id, sizeof m->id, "%s", data && data->pMessageIdName ? data->pMessageIdName : "");
        const char *text = data && data->pMessage ? data->pMessage : "";
        m->text = malloc(strlen(text) + 1);
        if (m->text)
            strcpy(m->text, text);
    }
    return drop_calls ? VK_TRUE : VK_FALSE;
}

HELPER void clear_messages(void) {
    for (int i = 0; i < message_count; i++)
        free(messages[i].text);
    message_count = 0;
}

HELPER const char *version_text(uint32_t v) {
    static char text[4][32];
    static int next;
    char *t = text[next++ % 4];
    snprintf(t, 32, "%u.%u.%u", VK_API_VERSION_MAJOR(v), VK_API_VERSION_MINOR(v), VK_API_VERSION_PATCH(v));
    return t;
}

/* Creates the instance (with the validation layer and a messenger when it is installed; `need_layer`:
 * the case cannot be judged without it), picks the first device and prints what runs the case. */
HELPER void start(int need_layer) {
    /* Line by line, so a driver that hangs or kills the program leaves what it printed so far. */
    setvbuf(stdout, NULL, _IOLBF, 0);
    const uint32_t one = 1;
    if (*(const uint8_t *)&one != 1) {
        fprintf(stderr, "rtconf reproducer: the embedded data is little-endian; this host is not\n");
        exit(2);
    }
    uint32_t n = 0;
    vkEnumerateInstanceLayerProperties(&n, NULL);
    VkLayerProperties *layers = calloc(n ? n : 1, sizeof *layers);
    vkEnumerateInstanceLayerProperties(&n, layers);
    int layer = -1;
    for (uint32_t i = 0; i < n; i++)
        if (strcmp(layers[i].layerName, "VK_LAYER_KHRONOS_validation") == 0)
            layer = (int)i;
    if (layer < 0) {
        if (need_layer) {
            fprintf(stderr, "rtconf reproducer: VK_LAYER_KHRONOS_validation is not installed; this case is "
                            "judged by the layer (Debian: apt-get install vulkan-validationlayers)\n");
            exit(2);
        }
        printf("layer:   VK_LAYER_KHRONOS_validation is not installed (running without it)\n");
    } else {
        printf("layer:   VK_LAYER_KHRONOS_validation %s (implementation %u)\n",
               version_text(layers[layer].specVersion), layers[layer].implementationVersion);
    }
    const char *layer_names[] = {"VK_LAYER_KHRONOS_validation"};
    const char *extension_names[] = {VK_EXT_DEBUG_UTILS_EXTENSION_NAME};
    VkApplicationInfo app = {VK_STRUCTURE_TYPE_APPLICATION_INFO};
    app.pApplicationName = "rtconf";
    app.apiVersion = VK_API_VERSION_1_3;
    VkInstanceCreateInfo info = {VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
    info.pApplicationInfo = &app;
    info.enabledLayerCount = layer >= 0 ? 1 : 0;
    info.ppEnabledLayerNames = layer_names;
    info.enabledExtensionCount = layer >= 0 ? 1 : 0;
    info.ppEnabledExtensionNames = extension_names;
    CHECK(vkCreateInstance(&info, NULL, &instance));
    free(layers);
    if (layer >= 0) {
        VkDebugUtilsMessengerCreateInfoEXT m = {VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
        m.messageSeverity =
            VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT;
        m.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                        VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
        m.pfnUserCallback = on_message;
        PFN_vkCreateDebugUtilsMessengerEXT create =
            (PFN_vkCreateDebugUtilsMessengerEXT)vkGetInstanceProcAddr(instance, "vkCreateDebugUtilsMessengerEXT");
        if (!create)
            fail("vkGetInstanceProcAddr(vkCreateDebugUtilsMessengerEXT)", VK_ERROR_EXTENSION_NOT_PRESENT);
        CHECK(create(instance, &m, NULL, &messenger));
    }
    uint32_t count = 1;
    VkResult r = vkEnumeratePhysicalDevices(instance, &count, &physical);
    if ((r != VK_SUCCESS && r != VK_INCOMPLETE) || count == 0) {
        fprintf(stderr, "rtconf reproducer: no Vulkan device (VK_DRIVER_FILES selects the driver's ICD json)\n");
        exit(2);
    }
    VkPhysicalDeviceDriverProperties driver = {VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES};
    VkPhysicalDeviceProperties2 p2 = {VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2, &driver};
    vkGetPhysicalDeviceProperties2(physical, &p2);
    device_properties = p2.properties;
    printf("device:  %s (vendor 0x%04x, device 0x%04x), Vulkan %s\n", device_properties.deviceName,
           device_properties.vendorID, device_properties.deviceID, version_text(device_properties.apiVersion));
    printf("driver:  %s %s (driver version 0x%08x)\n", driver.driverName, driver.driverInfo,
           device_properties.driverVersion);
    if (device_properties.apiVersion < VK_API_VERSION_1_3) {
        fprintf(stderr, "rtconf reproducer: the device offers Vulkan %s; the case's device is made as on Vulkan 1.3\n",
                version_text(device_properties.apiVersion));
        exit(2);
    }
    vkGetPhysicalDeviceMemoryProperties(physical, &memory_properties);
    uint32_t families = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(physical, &families, NULL);
    VkQueueFamilyProperties *props = calloc(families ? families : 1, sizeof *props);
    vkGetPhysicalDeviceQueueFamilyProperties(physical, &families, props);
    queue_family = UINT32_MAX;
    for (uint32_t i = 0; i < families && queue_family == UINT32_MAX; i++)
        if (props[i].queueFlags & VK_QUEUE_COMPUTE_BIT)
            queue_family = i;
    free(props);
    if (queue_family == UINT32_MAX) {
        fprintf(stderr, "rtconf reproducer: no queue family with VK_QUEUE_COMPUTE_BIT\n");
        exit(2);
    }
}

/* Whether the device exposes an extension. */
HELPER int has_extension(const char *name) {
    uint32_t n = 0;
    vkEnumerateDeviceExtensionProperties(physical, NULL, &n, NULL);
    VkExtensionProperties *e = calloc(n ? n : 1, sizeof *e);
    vkEnumerateDeviceExtensionProperties(physical, NULL, &n, e);
    int found = 0;
    for (uint32_t i = 0; i < n; i++)
        found |= strcmp(e[i].extensionName, name) == 0;
    free(e);
    return found;
}

/* Device functions of extensions, loaded once the device exists (NULL where the case does not enable
 * the extension). */
static PFN_vkCreateAccelerationStructureKHR pvkCreateAccelerationStructureKHR;
static PFN_vkGetAccelerationStructureBuildSizesKHR pvkGetAccelerationStructureBuildSizesKHR;
static PFN_vkGetAccelerationStructureDeviceAddressKHR pvkGetAccelerationStructureDeviceAddressKHR;
static PFN_vkCmdBuildAccelerationStructuresKHR pvkCmdBuildAccelerationStructuresKHR;
static PFN_vkCmdBuildAccelerationStructuresIndirectKHR pvkCmdBuildAccelerationStructuresIndirectKHR;
static PFN_vkCreateRayTracingPipelinesKHR pvkCreateRayTracingPipelinesKHR;
static PFN_vkGetRayTracingShaderGroupHandlesKHR pvkGetRayTracingShaderGroupHandlesKHR;
static PFN_vkGetRayTracingShaderGroupStackSizeKHR pvkGetRayTracingShaderGroupStackSizeKHR;
static PFN_vkCmdSetRayTracingPipelineStackSizeKHR pvkCmdSetRayTracingPipelineStackSizeKHR;
static PFN_vkCmdTraceRaysKHR pvkCmdTraceRaysKHR;
static PFN_vkCmdTraceRaysIndirectKHR pvkCmdTraceRaysIndirectKHR;

#define LOAD(name) p##name = (PFN_##name)vkGetDeviceProcAddr(device, #name)

/* Creates the device with exactly the case's extensions and features, its queue, a command pool with a
 * primary and a secondary command buffer, and a fence. */
HELPER void make_device(const char *const *extensions, uint32_t extension_count, const void *features,
                        const VkPhysicalDeviceFeatures *core) {
    float priority = 1.0f;
    VkDeviceQueueCreateInfo q = {VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    q.queueFamilyIndex = queue_family;
    q.queueCount = 1;
    q.pQueuePriorities = &priority;
    VkDeviceCreateInfo info = {VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    info.pNext = features;
    info.queueCreateInfoCount = 1;
    info.pQueueCreateInfos = &q;
    info.enabledExtensionCount = extension_count;
    info.ppEnabledExtensionNames = extensions;
    info.pEnabledFeatures = core;
    CHECK(vkCreateDevice(physical, &info, NULL, &device));
    vkGetDeviceQueue(device, queue_family, 0, &queue);
    LOAD(vkCreateAccelerationStructureKHR);
    LOAD(vkGetAccelerationStructureBuildSizesKHR);
    LOAD(vkGetAccelerationStructureDeviceAddressKHR);
    LOAD(vkCmdBuildAccelerationStructuresKHR);
    LOAD(vkCmdBuildAccelerationStructuresIndirectKHR);
    LOAD(vkCreateRayTracingPipelinesKHR);
    LOAD(vkGetRayTracingShaderGroupHandlesKHR);
    LOAD(vkGetRayTracingShaderGroupStackSizeKHR);
    LOAD(vkCmdSetRayTracingPipelineStackSizeKHR);
    LOAD(vkCmdTraceRaysKHR);
    LOAD(vkCmdTraceRaysIndirectKHR);
    VkCommandPoolCreateInfo p = {VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    p.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    p.queueFamilyIndex = queue_family;
    CHECK(vkCreateCommandPool(device, &p, NULL, &pool));
    VkCommandBufferAllocateInfo a = {VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    a.commandPool = pool;
    a.commandBufferCount = 1;
    a.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    CHECK(vkAllocateCommandBuffers(device, &a, &primary));
    a.level = VK_COMMAND_BUFFER_LEVEL_SECONDARY;
    CHECK(vkAllocateCommandBuffers(device, &a, &secondary));
    VkFenceCreateInfo f = {VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    CHECK(vkCreateFence(device, &f, NULL, &fence));
}

/* A buffer in host-visible memory, mapped, at a device address that is a multiple of `align`. */
struct buffer {
    VkBuffer buffer;
    VkDeviceMemory memory;
    VkDeviceAddress address;
    VkDeviceSize size;
    uint8_t *map;
    int coherent;
};

HELPER uint32_t host_memory_type(uint32_t bits, int *coherent) {
    VkMemoryPropertyFlags visible = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT;
    for (int pass = 0; pass < 2; pass++) {
        VkMemoryPropertyFlags want = pass == 0 ? visible | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT : visible;
        for (uint32_t i = 0; i < memory_properties.memoryTypeCount; i++)
            if ((bits & (1u << i)) && (memory_properties.memoryTypes[i].propertyFlags & want) == want) {
                *coherent = pass == 0;
                return i;
            }
    }
    fprintf(stderr, "rtconf reproducer: no host-visible memory type for a buffer\n");
    exit(2);
}

HELPER VkDeviceAddress buffer_address(VkBuffer b) {
    if (!buffer_device_address)
        return 0;
    VkBufferDeviceAddressInfo info = {VK_STRUCTURE_TYPE_BUFFER_DEVICE_ADDRESS_INFO};
    info.buffer = b;
    return vkGetBufferDeviceAddress(device, &info);
}

HELPER VkBuffer create_buffer(VkDeviceSize size, VkBufferUsageFlags usage, VkBufferCreateFlags flags) {
    VkBufferCreateInfo info = {VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    info.size = size ? size : 1;
    info.usage = usage;
    info.flags = flags;
    VkBuffer b;
    CHECK(vkCreateBuffer(device, &info, NULL, &b));
    return b;
}

HELPER struct buffer make_buffer(VkDeviceSize size, VkBufferUsageFlags usage, VkBufferCreateFlags flags,
                                 VkDeviceSize align) {
    struct buffer b = {0};
    b.size = size;
    b.buffer = create_buffer(size, usage, flags);
    VkMemoryRequirements req;
    vkGetBufferMemoryRequirements(device, b.buffer, &req);
    uint32_t type = host_memory_type(req.memoryTypeBits, &b.coherent);
    VkMemoryAllocateFlagsInfo address_flags = {VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_FLAGS_INFO};
    address_flags.flags = VK_MEMORY_ALLOCATE_DEVICE_ADDRESS_BIT;
    VkMemoryAllocateInfo alloc = {VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    alloc.pNext = buffer_device_address ? &address_flags : NULL;
    alloc.allocationSize = req.size + (align > 1 ? align : 0);
    alloc.memoryTypeIndex = type;
    CHECK(vkAllocateMemory(device, &alloc, NULL, &b.memory));
    CHECK(vkBindBufferMemory(device, b.buffer, b.memory, 0));
    b.address = buffer_address(b.buffer);
    VkDeviceSize offset = 0;
    if (buffer_device_address && align > 1 && b.address % align != 0) {
        /* An identical buffer bound at the offset that aligns its address. */
        VkDeviceSize delta = align - b.address % align;
        if (delta % (req.alignment ? req.alignment : 1) != 0) {
            fprintf(stderr, "rtconf reproducer: cannot place a buffer at a %llu-aligned address\n",
                    (unsigned long long)align);
            exit(2);
        }
        vkDestroyBuffer(device, b.buffer, NULL);
        b.buffer = create_buffer(size, usage, flags);
        CHECK(vkBindBufferMemory(device, b.buffer, b.memory, delta));
        offset = delta;
        b.address = buffer_address(b.buffer);
    }
    void *map;
    CHECK(vkMapMemory(device, b.memory, 0, VK_WHOLE_SIZE, 0, &map));
    b.map = (uint8_t *)map + offset;
    return b;
}

HELPER void flush(const struct buffer *b) {
    if (b->coherent)
        return;
    VkMappedMemoryRange r = {VK_STRUCTURE_TYPE_MAPPED_MEMORY_RANGE};
    r.memory = b->memory;
    r.size = VK_WHOLE_SIZE;
    vkFlushMappedMemoryRanges(device, 1, &r);
}

/* Writes bytes at `offset`, cut at the buffer's end (as the harness writes a case's contents). */
HELPER void write_bytes(struct buffer *b, VkDeviceSize offset, const void *bytes, size_t n) {
    if (offset >= b->size)
        return;
    if (offset + n > b->size)
        n = (size_t)(b->size - offset);
    memcpy(b->map + offset, bytes, n);
    flush(b);
}

/* A memory image: the buffer zeroed, then its first `n` bytes (none: only zeroed; the runs a case
   writes further on follow with write_bytes). */
HELPER void write_image(struct buffer *b, const void *bytes, size_t n) {
    memset(b->map, 0, (size_t)b->size);
    if (n)
        write_bytes(b, 0, bytes, n);
    else
        flush(b);
}

HELPER void write_u64(struct buffer *b, VkDeviceSize offset, uint64_t value, size_t n) {
    uint8_t le[8];
    for (int i = 0; i < 8; i++)
        le[i] = (uint8_t)(value >> (8 * i));
    write_bytes(b, offset, le, n);
}

HELPER const uint32_t *read_words(const struct buffer *b) {
    if (!b->coherent) {
        VkMappedMemoryRange r = {VK_STRUCTURE_TYPE_MAPPED_MEMORY_RANGE};
        r.memory = b->memory;
        r.size = VK_WHOLE_SIZE;
        vkInvalidateMappedMemoryRanges(device, 1, &r);
    }
    return (const uint32_t *)b->map;
}

HELPER void begin_one_time(VkCommandBuffer cb) {
    CHECK(vkResetCommandBuffer(cb, 0));
    VkCommandBufferBeginInfo begin = {VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    CHECK(vkBeginCommandBuffer(cb, &begin));
}

HELPER void submit_and_wait(VkCommandBuffer cb) {
    VkSubmitInfo submit = {VK_STRUCTURE_TYPE_SUBMIT_INFO};
    submit.commandBufferCount = 1;
    submit.pCommandBuffers = &cb;
    CHECK(vkQueueSubmit(queue, 1, &submit, fence));
    VkResult waited = vkWaitForFences(device, 1, &fence, VK_TRUE, 20ull * 1000 * 1000 * 1000);
    if (waited == VK_TIMEOUT) {
        /* Nothing the case submits runs for seconds: a work that has not finished in 20 s hangs. */
        printf("verdict: the submitted work did not finish within 20 s (the device hangs)\n");
        exit(1);
    }
    CHECK(waited);
    CHECK(vkResetFences(device, 1, &fence));
}

HELPER void memory_barrier(VkCommandBuffer cb, VkPipelineStageFlags src_stage, VkAccessFlags src_access,
                           VkPipelineStageFlags dst_stage, VkAccessFlags dst_access) {
    VkMemoryBarrier b = {VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    b.srcAccessMask = src_access;
    b.dstAccessMask = dst_access;
    vkCmdPipelineBarrier(cb, src_stage, dst_stage, 0, 1, &b, 0, NULL, 0, NULL);
}

/* An empty render pass and its 1x1 framebuffer, for calls recorded inside one. */
static VkRenderPass render_pass;
static VkFramebuffer framebuffer;
HELPER void make_render_pass(void) {
    VkSubpassDescription sub = {0};
    sub.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS;
    VkRenderPassCreateInfo rp = {VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO};
    rp.subpassCount = 1;
    rp.pSubpasses = &sub;
    CHECK(vkCreateRenderPass(device, &rp, NULL, &render_pass));
    VkFramebufferCreateInfo fb = {VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO};
    fb.renderPass = render_pass;
    fb.width = 1;
    fb.height = 1;
    fb.layers = 1;
    CHECK(vkCreateFramebuffer(device, &fb, NULL, &framebuffer));
}

HELPER void begin_render_pass(VkCommandBuffer cb, VkSubpassContents contents) {
    VkRenderPassBeginInfo begin = {VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO};
    begin.renderPass = render_pass;
    begin.framebuffer = framebuffer;
    begin.renderArea.extent.width = 1;
    begin.renderArea.extent.height = 1;
    vkCmdBeginRenderPass(cb, &begin, contents);
}

/* Prints every message of the layer in full, then the sorted unique ids of its errors on one line, and
 * returns how many of those ids are not among `expected` plus how many of `expected` are missing. */
HELPER int report_layer(const char *const *expected, int expected_count) {
    for (int i = 0; i < message_count; i++)
        printf("  [%s] %s\n    %s\n", messages[i].severity, messages[i].id, messages[i].text);
    const char *ids[MAX_MESSAGES];
    int n = 0;
    for (int i = 0; i < message_count; i++) {
        if (strcmp(messages[i].severity, "error") != 0 || messages[i].id[0] == 0)
            continue;
        int seen = 0;
        for (int k = 0; k < n; k++)
            seen |= strcmp(ids[k], messages[i].id) == 0;
        if (!seen)
            ids[n++] = messages[i].id;
    }
    for (int i = 1; i < n; i++)
        for (int k = i; k > 0 && strcmp(ids[k - 1], ids[k]) > 0; k--) {
            const char *t = ids[k];
            ids[k] = ids[k - 1];
            ids[k - 1] = t;
        }
    printf("layer reported: ");
    for (int i = 0; i < n; i++)
        printf("%s%s", i ? ", " : "", ids[i]);
    printf("%s\n", n ? "" : "nothing");
    int differ = 0;
    for (int i = 0; i < n; i++) {
        int found = 0;
        for (int k = 0; k < expected_count; k++)
            found |= strcmp(ids[i], expected[k]) == 0;
        if (!found) {
            printf("  layer only: %s\n", ids[i]);
            differ++;
        }
    }
    for (int k = 0; k < expected_count; k++) {
        int found = 0;
        for (int i = 0; i < n; i++)
            found |= strcmp(ids[i], expected[k]) == 0;
        if (!found) {
            printf("  model only: %s\n", expected[k]);
            differ++;
        }
    }
    return differ;
}

/* Builds one structure directly and waits: `info` with `ranges`, its writes made visible to later
 * builds and compute shaders (what the build check reads it with). */
HELPER void build_and_wait(const VkAccelerationStructureBuildGeometryInfoKHR *info,
                           const VkAccelerationStructureBuildRangeInfoKHR *ranges) {
    begin_one_time(primary);
    pvkCmdBuildAccelerationStructuresKHR(primary, 1, info, &ranges);
    memory_barrier(primary, VK_PIPELINE_STAGE_ACCELERATION_STRUCTURE_BUILD_BIT_KHR,
                   VK_ACCESS_ACCELERATION_STRUCTURE_WRITE_BIT_KHR,
                   VK_PIPELINE_STAGE_ACCELERATION_STRUCTURE_BUILD_BIT_KHR | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                   VK_ACCESS_ACCELERATION_STRUCTURE_READ_BIT_KHR);
    CHECK(vkEndCommandBuffer(primary));
    submit_and_wait(primary);
}

/* A descriptor pool of `count` pool sizes and `max_sets` sets, and one set of `layout` from it. */
HELPER VkDescriptorSet one_set(VkDescriptorSetLayout layout, const VkDescriptorPoolSize *sizes, uint32_t count,
                               uint32_t max_sets) {
    VkDescriptorPoolCreateInfo pool_info = {VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
    pool_info.maxSets = max_sets;
    pool_info.poolSizeCount = count;
    pool_info.pPoolSizes = sizes;
    VkDescriptorPool descriptor_pool;
    CHECK(vkCreateDescriptorPool(device, &pool_info, NULL, &descriptor_pool));
    VkDescriptorSetAllocateInfo set_alloc = {VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    set_alloc.descriptorPool = descriptor_pool;
    set_alloc.descriptorSetCount = 1;
    set_alloc.pSetLayouts = &layout;
    VkDescriptorSet set;
    CHECK(vkAllocateDescriptorSets(device, &set_alloc, &set));
    return set;
}

/* Prints the layer's messages since the last clear_messages about the harness's own calls (`what`), which
 * must draw no error, and clears them; returns how many errors there were. */
HELPER int report_own_calls(const char *what) {
    int errors = 0;
    for (int i = 0; i < message_count; i++) {
        printf("  [%s] %s\n    %s\n", messages[i].severity, messages[i].id, messages[i].text);
        errors += strcmp(messages[i].severity, "error") == 0;
    }
    printf("         %s: %s\n", what, errors ? "the layer reported errors" : "no layer error");
    clear_messages();
    return errors;
}

/* The spec's default pipeline stack size ("Ray Tracing Pipeline Stack"): raygen + min(1, depth) x
 * max(closest hit, miss, intersection + any hit) + max(0, depth - 1) x max(closest hit, miss) + 2 x
 * callable, each the largest stack size of its kind (general stages count in all three general kinds). */
HELPER uint32_t default_stack_size(VkPipeline pipeline, const VkRayTracingShaderGroupCreateInfoKHR *groups,
                                   uint32_t count, uint32_t depth) {
    VkDeviceSize raygen = 0, miss = 0, callable = 0, closest = 0, any = 0, isect = 0;
#define MAX_OF(a, b) ((a) > (b) ? (a) : (b))
    for (uint32_t g = 0; g < count; g++) {
        if (groups[g].type == VK_RAY_TRACING_SHADER_GROUP_TYPE_GENERAL_KHR &&
            groups[g].generalShader != VK_SHADER_UNUSED_KHR) {
            VkDeviceSize s = pvkGetRayTracingShaderGroupStackSizeKHR(device, pipeline, g, VK_SHADER_GROUP_SHADER_GENERAL_KHR);
            raygen = MAX_OF(raygen, s);
            miss = MAX_OF(miss, s);
            callable = MAX_OF(callable, s);
        }
        if (groups[g].closestHitShader != VK_SHADER_UNUSED_KHR)
            closest = MAX_OF(closest, pvkGetRayTracingShaderGroupStackSizeKHR(device, pipeline, g,
                                                                               VK_SHADER_GROUP_SHADER_CLOSEST_HIT_KHR));
        if (groups[g].anyHitShader != VK_SHADER_UNUSED_KHR)
            any = MAX_OF(any, pvkGetRayTracingShaderGroupStackSizeKHR(device, pipeline, g, VK_SHADER_GROUP_SHADER_ANY_HIT_KHR));
        if (groups[g].intersectionShader != VK_SHADER_UNUSED_KHR)
            isect = MAX_OF(isect, pvkGetRayTracingShaderGroupStackSizeKHR(device, pipeline, g,
                                                                           VK_SHADER_GROUP_SHADER_INTERSECTION_KHR));
    }
    VkDeviceSize d = depth;
    VkDeviceSize total = raygen + (d < 1 ? d : 1) * MAX_OF(MAX_OF(closest, miss), isect + any) +
                         (d > 1 ? d - 1 : 0) * MAX_OF(closest, miss) + 2 * callable;
#undef MAX_OF
    return total > UINT32_MAX ? UINT32_MAX : (uint32_t)total;
}

/* ---- A valid launch's ray records (model/src/tracer/record.rs: 28 words per launch ID) judged against
 * the model's tables, as model::tracer::judge judges them. ---- */
#define RECORD_WORDS 28
/* What one record stands for in what the judge prints: a launch ID, or a ray of a build's check. */
static const char *record_of = "launch ID";
#define SEEN_SLOTS 4
#define OUTCOME_NOT_RUN 0xFFFFFFFFu
#define OUTCOME_MISS 1u
#define OUTCOME_HIT 2u
#define OUTCOME_NO_SHADER 3u
#define NO_GROUP 0xFFFFFFFFu
#define UNBOUNDED 0xFFFFFFFFu

/* What one distinct ray may do. */
struct ray_rule {
    uint8_t miss_allowed, miss_zero_group;
    uint32_t miss_group;
    uint8_t no_shader_allowed, skip_closest_hit, vary;
    uint32_t any_min, any_max, isect_min, isect_max;
    uint32_t first_candidate, candidates, first_group, groups;
};
/* A primitive that may become a candidate of the ray. */
struct candidate_rule {
    uint32_t instance, geometry, primitive;
    uint8_t committable, runs_any_hit, no_duplicate, runs_closest_hit;
    uint32_t group, custom_index, first_report, reports;
};
/* One hit a candidate may be committed as: its hit kind, t interval and barycentric intervals. */
struct report_rule {
    uint32_t hit_kind;
    double t_lo, t_hi;
    int bary;
    double b_lo, b_hi, c_lo, c_hi;
};
/* A shared edge or closed fan: its members must not both be hit. */
struct watertight_rule {
    uint32_t first_member, members;
};
struct primitive_ref {
    uint32_t instance, geometry, primitive;
};
struct launch_rules {
    const struct ray_rule *rays;
    uint32_t ray_count;
    const struct candidate_rule *candidates;
    const struct report_rule *reports;
    const struct watertight_rule *groups;
    const struct primitive_ref *members;
};

HELPER float word_float(uint32_t w) {
    float f;
    memcpy(&f, &w, 4);
    return f;
}

HELPER int in_interval(double x, double lo, double hi) { return lo <= x && x <= hi; }

HELPER const struct candidate_rule *find_candidate(const struct launch_rules *l, const struct ray_rule *r,
                                                   uint32_t instance, uint32_t geometry, uint32_t primitive) {
    for (uint32_t i = 0; i < r->candidates; i++) {
        const struct candidate_rule *c = &l->candidates[r->first_candidate + i];
        if (c->instance == instance && c->geometry == geometry && c->primitive == primitive)
            return c;
    }
    return NULL;
}

#define RECORD_FAIL(...)                                                                          \
    do {                                                                                          \
        fails++;                                                                                  \
        if (print) {                                                                              \
            printf("  %s %llu (ray %u): ", record_of, (unsigned long long)id, ray);               \
            printf(__VA_ARGS__);                                                                  \
            printf("\n");                                                                         \
        }                                                                                         \
    } while (0)

/* Judges one launch ID's record `w` against the rule of its ray; prints each REQ violation when
 * `print`; returns how many it found. */
HELPER int judge_record(const struct launch_rules *l, uint64_t id, const uint32_t *w, int print) {
    int fails = 0;
    uint32_t ray = (uint32_t)(id % l->ray_count);
    const struct ray_rule *r = &l->rays[ray];
    if (w[0] == OUTCOME_NOT_RUN) {
        RECORD_FAIL("the launch ID did not run");
        return fails;
    }
    uint32_t any = w[10], isect = w[11];
    if (any < r->any_min || (r->any_max != UNBOUNDED && any > r->any_max))
        RECORD_FAIL("%u any-hit invocations outside [%u, %u] (%u: unbounded)", any, r->any_min, r->any_max, UNBOUNDED);
    if (isect < r->isect_min || (r->isect_max != UNBOUNDED && isect > r->isect_max))
        RECORD_FAIL("%u intersection invocations outside [%u, %u] (%u: unbounded)", isect, r->isect_min, r->isect_max,
                    UNBOUNDED);
    uint32_t seen = any < SEEN_SLOTS ? any : SEEN_SLOTS;
    for (uint32_t s = 0; s < seen; s++) {
        const uint32_t *slot = &w[12 + 4 * s];
        float t = word_float(slot[3]);
        const struct candidate_rule *c = find_candidate(l, r, slot[0], slot[1], slot[2]);
        if (!c) {
            RECORD_FAIL("any-hit ran for instance %u geometry %u primitive %u, which cannot be a candidate", slot[0],
                        slot[1], slot[2]);
            continue;
        }
        if (!c->runs_any_hit) {
            RECORD_FAIL("any-hit ran for instance %u geometry %u primitive %u, whose candidate is opaque or has no "
                        "any-hit shader",
                        slot[0], slot[1], slot[2]);
            continue;
        }
        int within = 0;
        for (uint32_t k = 0; k < c->reports; k++) {
            const struct report_rule *rep = &l->reports[c->first_report + k];
            within |= in_interval(t, rep->t_lo, rep->t_hi);
        }
        if (!within)
            RECORD_FAIL("any-hit saw instance %u geometry %u primitive %u at t = %.9g outside its bound", slot[0],
                        slot[1], slot[2], t);
        for (uint32_t p = 0; p < s && c->no_duplicate; p++)
            if (memcmp(&w[12 + 4 * p], slot, 12) == 0) {
                RECORD_FAIL("any-hit ran twice for instance %u geometry %u primitive %u with NO_DUPLICATE_ANY_HIT",
                            slot[0], slot[1], slot[2]);
                break;
            }
    }
    for (uint32_t g = 0; g < r->groups; g++) {
        const struct watertight_rule *group = &l->groups[r->first_group + g];
        uint32_t hit = 0;
        for (uint32_t m = 0; m < group->members; m++) {
            const struct primitive_ref *p = &l->members[group->first_member + m];
            int found = 0;
            for (uint32_t s = 0; s < seen; s++)
                found |= w[12 + 4 * s] == p->instance && w[13 + 4 * s] == p->geometry && w[14 + 4 * s] == p->primitive;
            hit += (uint32_t)found;
        }
        if (hit >= 2)
            RECORD_FAIL("double hit on a watertight group: %u of its triangles were seen", hit);
    }
    switch (w[0]) {
    case OUTCOME_MISS:
        if (!r->miss_allowed)
            RECORD_FAIL("missed, but a candidate must be hit");
        if (r->miss_zero_group)
            RECORD_FAIL("a miss shader ran, but the miss record is a zero group");
        else if (w[1] != r->miss_group)
            RECORD_FAIL("miss group %d, expected %u", (int)w[1], r->miss_group);
        break;
    case OUTCOME_NO_SHADER:
        if (!r->no_shader_allowed)
            RECORD_FAIL("neither a miss nor a closest-hit shader ran, but one must");
        break;
    case OUTCOME_HIT: {
        if (r->skip_closest_hit)
            RECORD_FAIL("closest-hit ran despite SkipClosestHitShader");
        const struct candidate_rule *c = find_candidate(l, r, w[2], w[4], w[5]);
        if (!c) {
            RECORD_FAIL("committed instance %u geometry %u primitive %u, which cannot be a candidate", w[2], w[4], w[5]);
            break;
        }
        if (!c->committable)
            RECORD_FAIL("committed instance %u geometry %u primitive %u, which cannot be the committed hit", w[2], w[4],
                        w[5]);
        if (!c->runs_closest_hit)
            RECORD_FAIL("closest-hit ran for a hit group without one");
        else if (w[1] != c->group)
            RECORD_FAIL("hit group %d, expected %u", (int)w[1], c->group);
        if (w[3] != c->custom_index)
            RECORD_FAIL("InstanceCustomIndex %u, expected %u", w[3], c->custom_index);
        const struct report_rule *rep = NULL;
        for (uint32_t k = 0; k < c->reports && !rep; k++)
            if (l->reports[c->first_report + k].hit_kind == w[6])
                rep = &l->reports[c->first_report + k];
        if (!rep) {
            RECORD_FAIL("HitKind 0x%x, which no report of the candidate has", w[6]);
            break;
        }
        float t = word_float(w[7]);
        if (!in_interval(t, rep->t_lo, rep->t_hi))
            RECORD_FAIL("t = %.9g outside [%.17g, %.17g]", t, rep->t_lo, rep->t_hi);
        if (rep->bary) {
            float b = word_float(w[8]), c2 = word_float(w[9]);
            if (!in_interval(b, rep->b_lo, rep->b_hi))
                RECORD_FAIL("barycentric b = %.9g outside [%.17g, %.17g]", b, rep->b_lo, rep->b_hi);
            if (!in_interval(c2, rep->c_lo, rep->c_hi))
                RECORD_FAIL("barycentric c = %.9g outside [%.17g, %.17g]", c2, rep->c_lo, rep->c_hi);
        }
        break;
    }
    default:
        RECORD_FAIL("word 0 (outcome) holds 0x%x, which names no outcome", w[0]);
    }
    return fails;
}

/* Judges every launch ID's record; prints the failures of the first ones and a summary line; returns
 * how many launch IDs violate a REQ rule. A launch that traces no ray must leave every record
 * "no shader". */
HELPER uint64_t judge_records(const struct launch_rules *l, const uint32_t *words, uint64_t ids) {
    uint64_t failed = 0, vary = 0;
    for (uint64_t id = 0; id < ids; id++) {
        const uint32_t *w = &words[id * RECORD_WORDS];
        int print = failed < 20;
        int fails;
        if (l->ray_count == 0) {
            uint32_t want[RECORD_WORDS];
            for (int k = 0; k < RECORD_WORDS; k++)
                want[k] = k == 0 ? OUTCOME_NO_SHADER : (k == 1 || k >= 12) ? 0xFFFFFFFFu : 0u;
            fails = memcmp(w, want, sizeof want) != 0;
            if (fails && print)
                printf("  launch ID %llu: the launch traces no ray, so its record must be \"no shader\"\n",
                       (unsigned long long)id);
        } else {
            vary += l->rays[id % l->ray_count].vary;
            fails = judge_record(l, id, w, print);
        }
        failed += fails > 0;
    }
    if (failed > 20)
        printf("  ... and %llu more %ss\n", (unsigned long long)(failed - 20), record_of);
    printf("records: %llu %ss judged (%llu REQ, %llu VARY), %llu violate the model\n", (unsigned long long)ids, record_of,
           (unsigned long long)(ids - vary), (unsigned long long)vary, (unsigned long long)failed);
    return failed;
}

/* Judges the records in `path` (little-endian words, RECORD_WORDS per launch ID, as --records writes
 * them) instead of running anything: 0 when every launch ID is the model's, 1 when one is not, 2 when
 * the file is not a launch of `ids` records. */
HELPER int judge_file(const struct launch_rules *l, const char *path, uint64_t ids) {
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "rtconf reproducer: cannot read %s\n", path);
        return 2;
    }
    size_t want = (size_t)ids * RECORD_WORDS;
    uint32_t *w = calloc(want ? want : 1, 4);
    if (!w) {
        fprintf(stderr, "rtconf reproducer: out of memory\n");
        return 2;
    }
    size_t got = fread(w, 4, want, f);
    int more = fgetc(f) != EOF;
    fclose(f);
    if (got != want || more) {
        fprintf(stderr, "rtconf reproducer: %s does not hold %llu records of %d words\n", path,
                (unsigned long long)ids, RECORD_WORDS);
        free(w);
        return 2;
    }
    uint64_t failed = judge_records(l, w, ids);
    free(w);
    if (failed)
        printf("output:  DIFFERS from the model at %llu %s(s)\n", (unsigned long long)failed, record_of);
    else
        printf("output:  matches the model (%llu %ss)\n", (unsigned long long)ids, record_of);
    return failed ? 1 : 0;
}

/* Writes the records read back to `path` (little-endian words), for comparing with rtconf's own run. */
HELPER void save_records(const char *path, const uint32_t *words, uint64_t count) {
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(words, 4, (size_t)count, f) != (size_t)count) {
        fprintf(stderr, "rtconf reproducer: cannot write %s\n", path);
        exit(2);
    }
    fclose(f);
}

/* ---- The case. ---- */
