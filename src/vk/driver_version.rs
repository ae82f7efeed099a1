//! Decoding of `VkPhysicalDeviceProperties::driverVersion`, whose bit layout is vendor-specific:
//! NVIDIA packs 10.8.8.6 bits, Intel's Windows driver 18.14, and everyone else (Mesa included)
//! uses the `VK_MAKE_VERSION` 10.10.12 layout. Also formats API versions.
use ash::vk;

pub const VENDOR_NVIDIA: u32 = 0x10de;
pub const VENDOR_INTEL: u32 = 0x8086;
pub const VENDOR_AMD: u32 = 0x1002;

/// A human-readable driver version for `vendor_id` / `driver_id`.
pub fn decode_driver_version(vendor_id: u32, driver_id: vk::DriverId, v: u32) -> String {
    if vendor_id == VENDOR_NVIDIA {
        let (a, b, c, d) = (v >> 22, (v >> 14) & 0xff, (v >> 6) & 0xff, v & 0x3f);
        // NVIDIA writes its versions as 580.159.04 (third part zero-padded to two digits).
        if d == 0 && c == 0 {
            return format!("{a}.{b}");
        }
        if d == 0 {
            return format!("{a}.{b}.{c:02}");
        }
        return format!("{a}.{b}.{c:02}.{d}");
    }
    if vendor_id == VENDOR_INTEL && driver_id == vk::DriverId::INTEL_PROPRIETARY_WINDOWS {
        return format!("{}.{}", v >> 14, v & 0x3fff);
    }
    format!("{}.{}.{}", v >> 22, (v >> 12) & 0x3ff, v & 0xfff)
}

/// `"25.0.7"` from a Mesa `driverInfo` such as `"Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6)"`.
pub fn mesa_version_from_info(info: &str) -> Option<String> {
    let rest = info.strip_prefix("Mesa ")?;
    let v: String = rest.chars().take_while(|c| c.is_ascii_digit() || *c == '.').collect();
    (v.split('.').count() >= 2 && !v.starts_with('.')).then(|| v.trim_end_matches('.').to_string())
}

pub fn format_api_version(v: u32) -> String {
    format!(
        "{}.{}.{}",
        vk::api_version_major(v),
        vk::api_version_minor(v),
        vk::api_version_patch(v)
    )
}

pub fn vendor_name(vendor_id: u32) -> &'static str {
    match vendor_id {
        VENDOR_NVIDIA => "NVIDIA",
        VENDOR_AMD => "AMD",
        VENDOR_INTEL => "Intel",
        0x13b5 => "ARM",
        0x5143 => "Qualcomm",
        0x1010 => "ImgTec",
        0x106b => "Apple",
        0x10005 => "Mesa",
        _ => "unknown",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nvidia_580() {
        // 580.95.05 packed as 10.8.8.6
        let v = (580 << 22) | (95 << 14) | (5 << 6);
        assert_eq!(
            decode_driver_version(VENDOR_NVIDIA, vk::DriverId::NVIDIA_PROPRIETARY, v),
            "580.95.05"
        );
        let v = (580 << 22) | (159 << 14) | (4 << 6);
        assert_eq!(
            decode_driver_version(VENDOR_NVIDIA, vk::DriverId::NVIDIA_PROPRIETARY, v),
            "580.159.04"
        );
        let v = (580 << 22) | (82 << 14);
        assert_eq!(
            decode_driver_version(VENDOR_NVIDIA, vk::DriverId::NVIDIA_PROPRIETARY, v),
            "580.82"
        );
    }

    #[test]
    fn mesa_uses_make_version() {
        let v = vk::make_api_version(0, 25, 0, 7);
        assert_eq!(decode_driver_version(0x10005, vk::DriverId::MESA_LLVMPIPE, v), "25.0.7");
    }

    #[test]
    fn mesa_version_from_driver_info() {
        assert_eq!(
            mesa_version_from_info("Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6)").as_deref(),
            Some("25.0.7")
        );
        assert_eq!(
            mesa_version_from_info("Mesa 24.1.0-devel (git-abc)").as_deref(),
            Some("24.1.0")
        );
        assert_eq!(mesa_version_from_info("580.95.05"), None);
    }

    #[test]
    fn intel_windows() {
        let v = (101 << 14) | 4314;
        assert_eq!(
            decode_driver_version(VENDOR_INTEL, vk::DriverId::INTEL_PROPRIETARY_WINDOWS, v),
            "101.4314"
        );
    }
}
