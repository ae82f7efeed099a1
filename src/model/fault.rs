//! What VK_EXT_device_fault reports after a device loss (the data; `vk::fault` queries it).
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FaultAddress {
    pub kind: String,
    pub address: String,
    pub precision: u64,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FaultVendorInfo {
    pub description: String,
    pub code: u64,
    pub data: u64,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FaultInfo {
    pub description: String,
    pub addresses: Vec<FaultAddress>,
    pub vendor: Vec<FaultVendorInfo>,
    pub vendor_binary_bytes: u64,
}
