//! The Vulkan instance: loading the loader, the optional validation layer with a debug messenger
//! that counts validation errors, those of them that report an invalid access
//! (`model::validation_message`), and warnings (and, asked for, GPU-Assisted Validation: the `gpuav_enable`
//! layer setting through VK_EXT_layer_settings where the layer offers that extension, else
//! VkValidationFeaturesEXT's GPU_ASSISTED enable, which is how layers before VK_EXT_layer_settings
//! such as Debian bookworm's 1.3.239 turn it on), and enumerating physical devices.
use super::error::{VkError, VkResultExt};
use crate::model::validation_message::{kind, MessageCounts, MessageKind};
use ash::{ext, vk};
use std::ffi::{c_void, CStr};
use std::sync::atomic::{AtomicU64, Ordering};

pub const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

static VALIDATION_ERRORS: AtomicU64 = AtomicU64::new(0);
static INVALID_ACCESS: AtomicU64 = AtomicU64::new(0);
static VALIDATION_WARNINGS: AtomicU64 = AtomicU64::new(0);

/// Number of validation-layer errors reported since the process started.
pub fn validation_error_count() -> u64 {
    VALIDATION_ERRORS.load(Ordering::Relaxed)
}

/// The messages since the process started by severity and kind (`model::validation_message`:
/// the errors that report an invalid access counted apart).
pub fn validation_counts() -> MessageCounts {
    MessageCounts {
        errors: VALIDATION_ERRORS.load(Ordering::Relaxed),
        invalid_access: INVALID_ACCESS.load(Ordering::Relaxed),
        warnings: VALIDATION_WARNINGS.load(Ordering::Relaxed),
    }
}

/// How many error messages' text is kept until [`take_validation_texts`], and how much of each.
pub const KEPT_TEXTS: usize = 4;
const KEPT_CHARS: usize = 400;
static VALIDATION_TEXTS: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());

/// Keep the first [`KEPT_TEXTS`] error messages (their VUID leads the layer's text), and GPU-AV's
/// setup warnings with them ([`keep`]).
fn keep_text(msg: &str) {
    if let Ok(mut kept) = VALIDATION_TEXTS.lock() {
        keep(&mut kept, msg.chars().take(KEPT_CHARS).collect());
    }
}

/// `text` into `kept`: among the first [`KEPT_TEXTS`]; past them, the first invalid access and
/// the first GPU-AV setup message still, each replacing the last message of neither kind — each
/// decides a GPU-AV verdict (`model::shader_gpu_av`: a setup message makes it `inconclusive`,
/// never `masks`).
fn keep(kept: &mut Vec<String>, text: String) {
    if kept.len() < KEPT_TEXTS {
        kept.push(text);
        return;
    }
    let k = kind(&text);
    if k != MessageKind::Other && !kept.iter().any(|t| kind(t) == k) {
        if let Some(slot) = kept.iter_mut().rev().find(|t| kind(t) == MessageKind::Other) {
            *slot = text;
        }
    }
}

/// The messages kept since the last call (the first few, shortened), and forget them.
pub fn take_validation_texts() -> Vec<String> {
    VALIDATION_TEXTS.lock().map(|mut k| std::mem::take(&mut *k)).unwrap_or_default()
}

#[derive(Clone, Debug, Default)]
pub struct InstanceOptions {
    /// Enable VK_LAYER_KHRONOS_validation when it is installed.
    pub validate: bool,
    /// With `validate`: GPU-Assisted Validation on too.
    pub gpu_av: bool,
}

/// How GPU-AV was turned on (the layer decides which it understands).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum GpuAvHow {
    /// VK_EXT_layer_settings, setting `gpuav_enable` = true.
    LayerSettings,
    /// VkValidationFeaturesEXT with VK_VALIDATION_FEATURE_ENABLE_GPU_ASSISTED_EXT.
    ValidationFeatures,
}

/// The first Vulkan headers of the 1.4 line (December 2024); VK_EXT_descriptor_heap was published
/// after them (2026), so a validation layer built from older headers cannot know the extension
/// and its GPU-AV cannot instrument heap shaders.
pub const HEAP_LAYER_MIN: u32 = vk::make_api_version(0, 1, 4, 303);

/// Why GPU-AV cannot check descriptor heap cells with a layer of `spec_version`, or `None`.
pub fn gpu_av_heap_gap(spec_version: u32) -> Option<String> {
    (spec_version < HEAP_LAYER_MIN).then(|| {
        format!(
            "validation layers {} predate VK_EXT_descriptor_heap",
            super::driver_version::format_api_version(spec_version)
        )
    })
}

pub struct Instance {
    pub entry: ash::Entry,
    pub raw: ash::Instance,
    /// Instance-level API version the loader supports.
    pub loader_version: u32,
    /// Whether the validation layer is active.
    pub validation: bool,
    debug: Option<(ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
}

unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    _user: *mut c_void,
) -> vk::Bool32 {
    let msg = if data.is_null() || (*data).p_message.is_null() {
        "<no message>".into()
    } else {
        CStr::from_ptr((*data).p_message).to_string_lossy()
    };
    // The message's id (its VUID) leads the text, where the layer did not put it there itself:
    // it is what `kind` reads.
    let id = if data.is_null() || (*data).p_message_id_name.is_null() {
        None
    } else {
        Some(CStr::from_ptr((*data).p_message_id_name).to_string_lossy())
    };
    let msg = match id {
        Some(id) if !id.is_empty() && !msg.contains(&*id) => format!("[ {id} ] {msg}").into(),
        _ => msg,
    };
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        VALIDATION_ERRORS.fetch_add(1, Ordering::Relaxed);
        if kind(&msg) == MessageKind::InvalidAccess {
            INVALID_ACCESS.fetch_add(1, Ordering::Relaxed);
        }
        keep_text(&msg);
        tracing::error!(target: "validation", "{msg}");
    } else if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING) {
        VALIDATION_WARNINGS.fetch_add(1, Ordering::Relaxed);
        // GPU-AV's setup warnings say it may not have checked what ran: kept, so a GPU-AV
        // verdict is `inconclusive`, never `masks`.
        if kind(&msg) == MessageKind::GpuAvSetup {
            keep_text(&msg);
        }
        tracing::warn!(target: "validation", "{msg}");
    } else {
        tracing::debug!(target: "validation", "{msg}");
    }
    vk::FALSE
}

/// The installed Khronos validation layer's properties, `None` without one.
fn validation_layer(entry: &ash::Entry) -> Result<Option<vk::LayerProperties>, VkError> {
    let available = unsafe { entry.enumerate_instance_layer_properties() }
        .at("vkEnumerateInstanceLayerProperties")?;
    Ok(available.into_iter().find(|l| l.layer_name_as_c_str() == Ok(VALIDATION_LAYER)))
}

/// The loader (`RTPROBE_VULKAN_LIB`, else the system's) and the instance version it supports,
/// refused below Vulkan 1.2.
fn load_entry() -> Result<(ash::Entry, u32), VkError> {
    // SAFETY: loading the system loader library; ash keeps it alive with the Entry.
    let entry = match std::env::var_os("RTPROBE_VULKAN_LIB") {
        Some(path) => unsafe { ash::Entry::load_from(&path) },
        None => unsafe { ash::Entry::load() },
    }
    .map_err(|e| VkError::LoaderMissing { detail: e.to_string() })?;

    let loader_version = unsafe { entry.try_enumerate_instance_version() }
        .at("vkEnumerateInstanceVersion")?
        .unwrap_or(vk::API_VERSION_1_0);
    if loader_version < vk::API_VERSION_1_2 {
        return Err(VkError::LoaderTooOld {
            found: super::driver_version::format_api_version(loader_version),
        });
    }
    Ok((entry, loader_version))
}

/// The layers and instance extensions asked for, and how GPU-AV is turned on.
#[derive(Default)]
struct Layers {
    layers: Vec<*const i8>,
    extensions: Vec<*const i8>,
    /// Whether the validation layer is active.
    validation: bool,
    /// How GPU-AV is turned on, when asked for and the layer is active.
    gpu_av: Option<GpuAvHow>,
}

impl Layers {
    /// The validation layer (and GPU-AV) when `opts` asks for it and it is installed.
    fn of(entry: &ash::Entry, opts: &InstanceOptions) -> Result<Layers, VkError> {
        let mut l = Layers::default();
        if !(opts.validate || opts.gpu_av) {
            return Ok(l);
        }
        if validation_layer(entry)?.is_none() {
            tracing::warn!("--validate: VK_LAYER_KHRONOS_validation is not installed (apt-get install vulkan-validationlayers); running without it");
            return Ok(l);
        }
        l.layers.push(VALIDATION_LAYER.as_ptr());
        l.extensions.push(ext::debug_utils::NAME.as_ptr());
        l.validation = true;
        if opts.gpu_av {
            let layer_exts =
                unsafe { entry.enumerate_instance_extension_properties(Some(VALIDATION_LAYER)) }
                    .at("vkEnumerateInstanceExtensionProperties")?;
            if layer_exts
                .iter()
                .any(|e| e.extension_name_as_c_str() == Ok(ext::layer_settings::NAME))
            {
                l.extensions.push(ext::layer_settings::NAME.as_ptr());
                l.gpu_av = Some(GpuAvHow::LayerSettings);
            } else {
                l.extensions.push(ext::validation_features::NAME.as_ptr());
                l.gpu_av = Some(GpuAvHow::ValidationFeatures);
            }
        }
        Ok(l)
    }

    /// `vkCreateInstance` with these layers and extensions (GPU-AV's setting chained as the layer
    /// understands it).
    fn create_instance(
        &self,
        entry: &ash::Entry,
        loader_version: u32,
    ) -> Result<ash::Instance, VkError> {
        let app = vk::ApplicationInfo::default()
            .application_name(c"rtprobe")
            .application_version(vk::make_api_version(0, 0, 1, 0))
            .engine_name(c"rtprobe")
            .api_version(vk::API_VERSION_1_3.min(loader_version));
        let mut info = vk::InstanceCreateInfo::default()
            .application_info(&app)
            .enabled_layer_names(&self.layers)
            .enabled_extension_names(&self.extensions);
        let on: [u8; 4] = vk::TRUE.to_ne_bytes();
        let settings = [vk::LayerSettingEXT::default()
            .layer_name(VALIDATION_LAYER)
            .setting_name(c"gpuav_enable")
            .ty(vk::LayerSettingTypeEXT::BOOL32)
            .values(&on)];
        let mut layer_settings = vk::LayerSettingsCreateInfoEXT::default().settings(&settings);
        let enables = [vk::ValidationFeatureEnableEXT::GPU_ASSISTED];
        let mut features =
            vk::ValidationFeaturesEXT::default().enabled_validation_features(&enables);
        match self.gpu_av {
            Some(GpuAvHow::LayerSettings) => info = info.push_next(&mut layer_settings),
            Some(GpuAvHow::ValidationFeatures) => info = info.push_next(&mut features),
            None => {}
        }
        match unsafe { entry.create_instance(&info, None) } {
            Ok(i) => Ok(i),
            Err(vk::Result::ERROR_INCOMPATIBLE_DRIVER) => Err(VkError::NoDriver {
                detail: "vkCreateInstance: VK_ERROR_INCOMPATIBLE_DRIVER".into(),
            }),
            Err(e) => Err(VkError::from_result("vkCreateInstance", e)),
        }
    }
}

/// The debug messenger that counts validation errors and warnings (performance warnings among
/// them) and logs them ([`debug_callback`]).
fn messenger(
    entry: &ash::Entry,
    raw: &ash::Instance,
) -> Result<(ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT), VkError> {
    let du = ext::debug_utils::Instance::new(entry, raw);
    let ci = vk::DebugUtilsMessengerCreateInfoEXT::default()
        .message_severity(
            vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
                | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
        )
        .message_type(
            vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                | vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
        )
        .pfn_user_callback(Some(debug_callback));
    let m = unsafe { du.create_debug_utils_messenger(&ci, None) }
        .at("vkCreateDebugUtilsMessengerEXT")?;
    Ok((du, m))
}

impl Instance {
    pub fn new(opts: &InstanceOptions) -> Result<Self, VkError> {
        let (entry, loader_version) = load_entry()?;
        let layers = Layers::of(&entry, opts)?;
        let raw = layers.create_instance(&entry, loader_version)?;
        let debug = if layers.validation { Some(messenger(&entry, &raw)?) } else { None };
        Ok(Self { entry, raw, loader_version, validation: layers.validation, debug })
    }

    /// The installed validation layer's specVersion (enabled or not), `None` without one.
    pub fn validation_layer_version(&self) -> Option<u32> {
        validation_layer(&self.entry).ok()?.map(|l| l.spec_version)
    }

    /// All physical devices, in the loader's order (that order is what `--device INDEX` means).
    pub fn physical_devices(&self) -> Result<Vec<vk::PhysicalDevice>, VkError> {
        let pds = match unsafe { self.raw.enumerate_physical_devices() } {
            Ok(p) => p,
            Err(vk::Result::ERROR_INITIALIZATION_FAILED) => Vec::new(),
            Err(e) => return Err(VkError::from_result("vkEnumeratePhysicalDevices", e)),
        };
        if pds.is_empty() {
            return Err(VkError::NoDriver { detail: "the loader found no physical device".into() });
        }
        Ok(pds)
    }
}

impl Drop for Instance {
    fn drop(&mut self) {
        unsafe {
            if let Some((du, m)) = self.debug.take() {
                du.destroy_debug_utils_messenger(m, None);
            }
            self.raw.destroy_instance(None);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layers_before_descriptor_heaps_are_told_apart_by_their_version() {
        assert_eq!(
            gpu_av_heap_gap(vk::make_api_version(0, 1, 3, 239)).as_deref(),
            Some("validation layers 1.3.239 predate VK_EXT_descriptor_heap")
        );
        assert_eq!(gpu_av_heap_gap(vk::make_api_version(0, 1, 4, 363)), None);
    }

    /// Past the first few messages an invalid access and a GPU-AV setup message are still kept,
    /// each once; other messages are not.
    #[test]
    fn access_and_setup_messages_are_kept_past_the_first_few() {
        let mut kept = Vec::new();
        for i in 0..KEPT_TEXTS + 2 {
            keep(&mut kept, format!("[ VUID-vkCmdTraceRaysKHR-None-0860{i} ] other"));
        }
        assert_eq!(kept.len(), KEPT_TEXTS);
        let setup = "[ WARNING-GPU-Assisted-Validation ] could not reserve a slot".to_string();
        let access = "[ VUID-vkCmdTraceRaysKHR-None-10068 ] Index of 63".to_string();
        keep(&mut kept, setup.clone());
        keep(&mut kept, access.clone());
        keep(&mut kept, "[ VUID-vkCmdTraceRaysKHR-None-10068 ] Index of 64".into());
        assert_eq!(kept.len(), KEPT_TEXTS);
        assert_eq!(kept.iter().filter(|t| **t == setup).count(), 1, "{kept:?}");
        assert_eq!(kept.iter().filter(|t| **t == access).count(), 1, "{kept:?}");
        assert!(kept[0].contains("08600"), "the first messages stay first: {kept:?}");
    }
}
