//! Command-line values of enums below the CLI: `clap::ValueEnum` written here, so that nothing
//! below the CLI knows clap. The data layer's names are the ones the report writes (serde's).
use crate::model::{DescriptorModel, Isolation, LaneMode, PatchMode, PipelineMode};
use crate::report::issue::Format;
use crate::shadergen::compile::TargetEnv;
use clap::builder::PossibleValue;

macro_rules! value_enum {
    ($t:ty { $($v:path => $name:literal $(: $help:literal)?),* $(,)? }) => {
        impl clap::ValueEnum for $t {
            fn value_variants<'a>() -> &'a [Self] {
                &[$($v),*]
            }
            fn to_possible_value(&self) -> Option<PossibleValue> {
                Some(match self {
                    $($v => PossibleValue::new($name)$(.help($help))?),*
                })
            }
        }
    };
}

value_enum!(Isolation {
    Isolation::Worker => "worker": "One worker runs many cells and is replaced after a fault",
    Isolation::ProcessPerCell => "process-per-cell": "Every cell runs in a fresh worker process",
});

value_enum!(PipelineMode {
    PipelineMode::Auto => "auto": "linked on GPUs that have VK_KHR_pipeline_library, whole on CPU devices",
    PipelineMode::Linked => "linked": "Each RT pipeline linked from one library per shader group, shared between cells",
    PipelineMode::Whole => "whole": "Each pipeline made from all its stages",
});

value_enum!(PatchMode {
    PatchMode::None => "none": "No patched cells",
    PatchMode::Faults => "faults": "After the run, retry each faulting cell with every workaround that applies to it",
    PatchMode::All => "all": "Plan every cell with every workaround that applies to it",
});

value_enum!(LaneMode {
    LaneMode::Auto => "auto": "Where the device lists subgroup ballot in the probed stage",
    LaneMode::Force => "force": "Also where it does not (a diagnosis: outside the spec there)",
    LaneMode::Off => "off": "Never",
});

value_enum!(DescriptorModel {
    DescriptorModel::DescriptorIndexing => "descriptor_indexing": "Descriptor sets (set/binding modules)",
    DescriptorModel::DescriptorBuffer => "descriptor_buffer": "Descriptor buffers, VK_EXT_descriptor_buffer (set/binding modules)",
    DescriptorModel::DescriptorHeap => "descriptor_heap": "Descriptor heaps, VK_EXT_descriptor_heap (modules that read a heap)",
});

value_enum!(TargetEnv {
    TargetEnv::Vulkan1_2 => "vulkan1.2": "Vulkan 1.2, SPIR-V 1.5 (what rtprobe's own shaders use)",
    TargetEnv::Vulkan1_3 => "vulkan1.3": "Vulkan 1.3, SPIR-V 1.6",
    TargetEnv::Vulkan1_4 => "vulkan1.4": "Vulkan 1.4, SPIR-V 1.6",
});

value_enum!(Format {
    Format::Md => "md",
    Format::Json => "json",
});

#[cfg(test)]
mod tests {
    use super::*;
    use clap::ValueEnum;

    #[test]
    fn command_line_names_are_the_report_names() {
        for v in Isolation::value_variants() {
            assert_eq!(serde_json::to_value(v).unwrap(), v.to_possible_value().unwrap().get_name());
        }
        for v in PatchMode::value_variants() {
            assert_eq!(serde_json::to_value(v).unwrap(), v.to_possible_value().unwrap().get_name());
        }
        for v in LaneMode::value_variants() {
            assert_eq!(serde_json::to_value(v).unwrap(), v.to_possible_value().unwrap().get_name());
            assert_eq!(v.as_str(), v.to_possible_value().unwrap().get_name());
        }
    }

    #[test]
    fn target_env_default_is_the_flags_default() {
        // `patch --target-env` defaults to "vulkan1.2"; `GlslOptions` defaults to this.
        assert_eq!(TargetEnv::default().to_possible_value().unwrap().get_name(), "vulkan1.2");
        assert_eq!(TargetEnv::from_str("vulkan1.4", false), Ok(TargetEnv::Vulkan1_4));
        for t in TargetEnv::value_variants() {
            assert_eq!(t.to_possible_value().unwrap().get_name(), t.name());
        }
        assert_eq!(Format::from_str("json", false), Ok(Format::Json));
    }
}
