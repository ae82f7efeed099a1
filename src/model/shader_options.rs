//! The options of `run --shader` that change what runs, beyond the inputs' own hashes: the entry
//! point, specialization constants (normalised), fills (a file's by its hash), runtime array and
//! sink sizes, a descriptor model other than the one the modules imply, a heap layout (by its
//! hash), what `--profile` turns on (by its effect, not its file), `--scene`'s file (by
//! its hash) and `--hit-group`'s ray types (sorted).
//! `shader_run::cell_id_with` names a run with them: the inputs' id as before when none is
//! given (reports written before these options keep their ids), else that id and `#` with 12 hex
//! digits of the options' FNV-1a 64 hash.
use serde::{Deserialize, Serialize};

/// What a run was given that changes what runs; absent fields were not given.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CellOptions {
    /// `--entry`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub entry: Option<String>,
    /// `--spec`, in a normal form (`harness::spec::canonical`: sorted by ID, each value as its
    /// type reads it back).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub spec: Vec<String>,
    /// `--fill`, each `TARGET=SOURCE` with a file source as `file:` and its content hash.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub fill: Vec<String>,
    /// `--array-size`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub array_size: Option<u64>,
    /// `--sink-size`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sink_size: Option<u64>,
    /// `--descriptor-model`, when it is not the model the modules imply.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub descriptor_model: Option<String>,
    /// `--heap-layout`: the content hash of its file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heap_layout: Option<String>,
    /// `--profile`'s effect on the harness, normalised: the robustness features it turns on
    /// and the binding flags it gives (not the file's bytes or name, so the same features in
    /// another file are the same cell). Empty: no profile, or one that changes nothing.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub profile: Vec<String>,
    /// `--scene`: the content hash of the scene file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene: Option<String>,
    /// `--hit-group`, each `K=FILE[,FILE…]` as given, sorted: which ray type a hit shader serves
    /// changes the pipeline.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub hit_groups: Vec<String>,
}

impl CellOptions {
    /// Whether no such option was given.
    pub fn is_empty(&self) -> bool {
        *self == CellOptions::default()
    }

    /// 16 hex digits of the FNV-1a 64 hash of every option, each field named and each value
    /// after its length (two different option sets never hash the same bytes).
    pub fn hash(&self) -> String {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut put = |bytes: &[u8]| {
            for b in (bytes.len() as u64).to_le_bytes().iter().chain(bytes) {
                h ^= *b as u64;
                h = h.wrapping_mul(0x0000_0100_0000_01b3);
            }
        };
        let opt = |o: &Option<String>| o.clone().unwrap_or_default();
        let num = |o: Option<u64>| o.map(|n| n.to_string()).unwrap_or_default();
        let fields: [(&str, Vec<String>); 7] = [
            ("entry", vec![opt(&self.entry)]),
            ("spec", self.spec.clone()),
            ("fill", self.fill.clone()),
            ("array_size", vec![num(self.array_size)]),
            ("sink_size", vec![num(self.sink_size)]),
            ("descriptor_model", vec![opt(&self.descriptor_model)]),
            ("heap_layout", vec![opt(&self.heap_layout)]),
        ];
        // Fields added later are hashed only when given: ids of runs without them stay.
        let scene = self.scene.iter().cloned().collect();
        let later = [
            ("profile", self.profile.clone()),
            ("scene", scene),
            ("hit_groups", self.hit_groups.clone()),
        ];
        let later = later.into_iter().filter(|(_, v)| !v.is_empty());
        for (name, values) in fields.into_iter().chain(later) {
            put(name.as_bytes());
            put(&(values.len() as u64).to_le_bytes());
            values.iter().for_each(|v| put(v.as_bytes()));
        }
        format!("{h:016x}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Old reports have no `cell_options`: they load as none.
    #[test]
    fn options_default_when_absent() {
        let o: CellOptions = serde_json::from_str("{}").unwrap();
        assert!(o.is_empty());
        let back: CellOptions = serde_json::from_str(
            &serde_json::to_string(&CellOptions { array_size: Some(8), ..o }).unwrap(),
        )
        .unwrap();
        assert_eq!(back.array_size, Some(8));
    }
}
