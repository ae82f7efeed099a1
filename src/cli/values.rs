//! Command-line values of the data layer's enums: `clap::ValueEnum` written here, so that nothing
//! below the CLI knows clap. The names are the ones the report writes (serde's).
use crate::model::{Isolation, PatchMode};
use clap::builder::PossibleValue;

macro_rules! value_enum {
    ($t:ty { $($v:path => $name:literal : $help:literal),* $(,)? }) => {
        impl clap::ValueEnum for $t {
            fn value_variants<'a>() -> &'a [Self] {
                &[$($v),*]
            }
            fn to_possible_value(&self) -> Option<PossibleValue> {
                Some(match self {
                    $($v => PossibleValue::new($name).help($help)),*
                })
            }
        }
    };
}

value_enum!(Isolation {
    Isolation::Worker => "worker": "One worker runs many cells and is replaced after a fault",
    Isolation::ProcessPerCell => "process-per-cell": "Every cell runs in a fresh worker process",
});

value_enum!(PatchMode {
    PatchMode::None => "none": "No patched cells",
    PatchMode::Faults => "faults": "After the run, retry each faulting cell with every workaround that applies to it",
    PatchMode::All => "all": "Plan every cell with every workaround that applies to it",
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
    }
}
