//! Comparison of a cell's records with the CPU reference: counts, worst errors, examples, a heap
//! cell's descriptor placement and set/binding mappings, and a mismatch in words
//! ([`mismatch_detail`], shared by the check that writes it and the renderers that read it back).
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Mismatch {
    pub pixel: [u32; 2],
    pub field: String,
    pub expected: String,
    pub actual: String,
}

/// What rtprobe accepts where the spec leaves a read undefined: its own heuristic, not the spec's.
pub const OTHER_LANE_HEURISTIC: &str = "rtprobe's heuristic for a scalarizing driver, not a rule of the spec (which leaves the read undefined): the value through the descriptor index another active lane of the same subgroup computed (from the lane evidence; without it, any lane of the dispatch), at the lane's own element";

/// Pixels of a cell without `nonuniformEXT` on its dynamic index (outside the spec's guarantees,
/// see [`NO_NONUNIFORM_VUID`]), by what they read.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ElementReads {
    /// The rule these cells break: the spec guarantees nothing about which element they read.
    pub outside_spec: String,
    /// What rtprobe accepted there instead ([`OTHER_LANE_HEURISTIC`]; empty in older reports,
    /// which accepted any element of the array).
    #[serde(default)]
    pub heuristic: String,
    /// Read their own element (as with `nonuniformEXT`).
    pub own: usize,
    /// Read what another lane's index gives (accepted by the heuristic).
    pub other: usize,
    /// Read neither: a mismatch.
    pub neither: usize,
    /// Pixels judged against their own subgroup's lanes (the device's lane evidence showed the
    /// whole subgroup); the others against every lane of the dispatch.
    #[serde(default)]
    pub by_subgroup: usize,
    /// Pixels judged exactly although their cell lacks `nonuniformEXT`: the device's lane
    /// evidence shows every active lane of their subgroup (two or more) computed the same index,
    /// so the read is uniform within the subgroup and needs no `NonUniform`
    /// (`VUID-RuntimeSpirv-subgroupSize-10149`, Vulkan 1.4.360). Counted in `own` / `neither`,
    /// not in the comparison's `any_element_values`.
    #[serde(default)]
    pub uniform: usize,
    /// Of `uniform`, pixels that mismatched: a defined read gone wrong, a finding like any other.
    #[serde(default)]
    pub uniform_mismatched: usize,
}

/// Where a heap cell's probed descriptors sit in the resource heap, and how its binding 2 reaches
/// them: what a driver engineer needs to recompute the address of the descriptor a lane should
/// have read.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct HeapDetail {
    /// Binding 2's `VkDescriptorSetAndBindingMappingEXT` (source and its fields), or that the
    /// shader reads the heap itself (`direct`).
    pub mapping: String,
    /// The shader record data after each hit group's SBT handle (hex bytes; empty: none).
    #[serde(default)]
    pub shader_record: String,
    /// Byte offset of the probed array's element 0 in the resource heap, and its stride: slot
    /// `s` is read from `probe_offset + s * probe_stride`.
    pub probe_offset: u32,
    pub probe_stride: u32,
    /// Every `VkDescriptorSetAndBindingMappingEXT` chained to the pipeline's stages, member by
    /// member, read back from the structs the executor hands the driver (empty in reports made
    /// before they were recorded).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub mappings: Vec<BindingMapping>,
}

/// One `VkDescriptorSetAndBindingMappingEXT` as the driver got it, its members named as in the
/// Vulkan registry (`vk.xml`, Vulkan 1.4.360).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct BindingMapping {
    pub descriptor_set: u32,
    pub first_binding: u32,
    pub binding_count: u32,
    /// `resourceMask`, e.g. `VK_SPIRV_RESOURCE_TYPE_ALL_EXT`.
    pub resource_mask: String,
    /// `source`, e.g. `VK_DESCRIPTOR_MAPPING_SOURCE_HEAP_WITH_SHADER_RECORD_INDEX_EXT`.
    pub source: String,
    /// The member of `sourceData` that `source` selects, e.g. `shaderRecordIndex`.
    pub source_member: String,
    /// That member's fields in declaration order: name and value (`pEmbeddedSampler` is `NULL`
    /// or says it points at a sampler; booleans are `VK_TRUE` / `VK_FALSE`).
    pub fields: Vec<(String, String)>,
}

impl BindingMapping {
    /// `descriptorSet 0, firstBinding 2, bindingCount 1, resourceMask …`.
    pub fn header(&self) -> String {
        format!(
            "descriptorSet {}, firstBinding {}, bindingCount {}, resourceMask {}",
            self.descriptor_set, self.first_binding, self.binding_count, self.resource_mask
        )
    }

    /// The source's sampler members (`pEmbeddedSampler`, `useCombinedImageSamplerIndex`,
    /// `sampler…`): `name value` joined by commas.
    pub fn sampler_fields(&self) -> String {
        let sampler = |n: &str| {
            n.starts_with("sampler")
                || n == "pEmbeddedSampler"
                || n == "useCombinedImageSamplerIndex"
        };
        let f: Vec<String> = self
            .fields
            .iter()
            .filter(|(n, _)| sampler(n))
            .map(|(n, v)| format!("{n} {v}"))
            .collect();
        f.join(", ")
    }

    /// The whole struct: `{ descriptorSet 0, …, source …, sourceData.shaderRecordIndex { … } }`.
    pub fn text(&self) -> String {
        let f: Vec<String> = self.fields.iter().map(|(n, v)| format!("{n} {v}")).collect();
        format!(
            "{{ {}, source {}, sourceData.{} {{ {} }} }}",
            self.header(),
            self.source,
            self.source_member,
            f.join(", ")
        )
    }
}

/// f64 figures that may be NaN or ∞: a number in JSON when finite, else "NaN" / "inf" / "-inf".
mod float_or_string {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        if v.is_finite() {
            v.serialize(s)
        } else {
            v.to_string().serialize(s)
        }
    }

    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Either {
        Num(f64),
        Text(String),
        Null(()),
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(match Either::deserialize(d)? {
            Either::Num(v) => v,
            Either::Text(t) => t.parse().map_err(serde::de::Error::custom)?,
            Either::Null(()) => f64::NAN,
        })
    }
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Comparison {
    pub pixels: usize,
    pub compared: usize,
    pub ambiguous: usize,
    pub mismatched_pixels: usize,
    /// Compared pixels on which the probed stage must run and its value is checked: the records an
    /// injected wrong value (`value:F`) can be caught on (`rtprobe bench`'s n).
    #[serde(default)]
    pub probe_checked: usize,
    /// Mismatch counts per field (stable order).
    pub by_field: std::collections::BTreeMap<String, usize>,
    /// Largest relative `t` error and absolute barycentric / value error seen on compared pixels
    /// (NaN when any compared value was NaN).
    #[serde(with = "float_or_string")]
    pub worst_t_rel: f64,
    #[serde(with = "float_or_string")]
    pub worst_bary: f64,
    #[serde(with = "float_or_string")]
    pub worst_value: f64,
    /// Pixels whose value was checked against every element of the array (see [`ValueRule`]).
    #[serde(default)]
    pub any_element_values: usize,
    /// Share of exactly checked probe pixels on which reading any other slot or element would
    /// have been caught; `None` when no probe pixel was checked exactly.
    #[serde(default)]
    pub discrimination: Option<f64>,
    /// Cells without `nonuniformEXT` on a dynamic index: what their pixels read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub element_reads: Option<ElementReads>,
    /// The first few mismatches, for the report.
    pub examples: Vec<Mismatch>,
    /// Whether the records carried the probed stage's lane evidence and whether it was judged by
    /// (absent in reports before lane evidence).
    #[serde(default)]
    pub lane_evidence: crate::model::LaneEvidence,
    /// Probe pixels whose subgroup's records contradict each other (`reference::lanes::
    /// contradictions`: garbage lane data): never used as evidence; a mismatch where the evidence
    /// is judged by.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub lane_contradictions: usize,
    /// For a mismatch whose records carry lane evidence: how the mismatched pixels split by it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lanes: Option<crate::model::LaneSplit>,
    /// Heap cells: where the probed descriptors sit in the heap and how binding 2 reaches them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heap: Option<HeapDetail>,
    /// Pictures of a mismatching comparison (expected, actual, diff PNGs; `run --dump`).
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub pictures: Vec<String>,
    /// A mutant attempt (`run --mutants`): what the reference, run with the same mutation,
    /// predicted this comparison would flag.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mutant: Option<MutantPrediction>,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

impl Comparison {
    pub fn passed(&self) -> bool {
        self.mismatched_pixels == 0
    }
}

/// A mismatch in words: how many pixels differ, in which fields, and for a read outside the spec's
/// guarantees which rule judged it ("924 of 4084 compared pixels differ (value 924)").
pub fn mismatch_detail(cmp: &Comparison) -> String {
    let fields: Vec<String> = cmp.by_field.iter().map(|(f, n)| format!("{f} {n}")).collect();
    let mut d = format!(
        "{} of {} compared pixels differ ({})",
        cmp.mismatched_pixels,
        cmp.compared,
        fields.join(", ")
    );
    let Some(e) = cmp.element_reads.as_ref() else { return d };
    let heuristic = e.neither.saturating_sub(e.uniform_mismatched);
    if heuristic > 0 {
        d.push_str(&format!(
            "; no nonuniformEXT ({}): {} pixels read an element no active lane of their subgroup indexed (rtprobe's scalarizing-driver heuristic, see docs/run.md)",
            e.outside_spec, heuristic
        ));
    }
    if e.uniform_mismatched > 0 {
        d.push_str(&format!(
            "; {} pixels of subgroups whose lanes all indexed one element read another (a uniform read, defined without nonuniformEXT: VUID-RuntimeSpirv-subgroupSize-10149, judged exactly)",
            e.uniform_mismatched
        ));
    }
    d
}

/// A stored attempt's `detail` with its counts in words: reports written before
/// [`mismatch_detail`] began it with the per-field map in debug form (`… differ ({"value": 926})`);
/// that opening is rewritten from the attempt's own comparison, the rest (notes after it) kept.
/// Any other detail comes back as it is.
pub fn detail_in_words(detail: &str, cmp: &Comparison) -> String {
    let old = format!(
        "{} of {} compared pixels differ ({:?})",
        cmp.mismatched_pixels, cmp.compared, cmp.by_field
    );
    match detail.strip_prefix(&old) {
        Some(rest) if !cmp.passed() => format!("{}{rest}", mismatch_detail(cmp)),
        _ => detail.to_string(),
    }
}

/// What the CPU reference, run with a mutant's mutation, predicts for a cell: on how many checked
/// pixels the records differ from the cell's own, and on how many of them the cell's comparison
/// must flag the difference (the rest its lenient rule allows). Carried in the mutant attempt's
/// comparison (`Comparison::mutant`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct MutantPrediction {
    /// Checked (non-ambiguous) pixels whose predicted record differs from the unmutated one.
    pub differing: usize,
    /// Of those, pixels the comparison with the unmutated reference must flag.
    pub caught: usize,
    /// Of `caught`, pixels judged by the other-lane heuristic (an undefined read, not in a
    /// uniform subgroup): the mutated read is undefined there too (no `NonUniform`), so what the
    /// driver reads is not the reference's to predict, and a survivor on them only is allowed.
    /// The rest of `caught` is judged exactly: a survivor there is a probe defect.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub caught_by_heuristic: usize,
    /// Predicted from the device's own lane evidence (`index-broadcast`: which lane led each
    /// subgroup), so decided after the run.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub from_lanes: bool,
}

impl MutantPrediction {
    /// Pixels the comparison must flag whatever an undefined read returns: judged exactly.
    pub fn caught_exactly(&self) -> usize {
        self.caught.saturating_sub(self.caught_by_heuristic)
    }

    /// The mutant applies: the reference predicts other records on some checked pixel.
    pub fn applicable(&self) -> bool {
        self.differing > 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mismatch_is_said_in_words_and_names_the_heuristic_when_it_judged() {
        let mut c = Comparison { compared: 4084, mismatched_pixels: 924, ..Default::default() };
        c.by_field.insert("value".into(), 924);
        assert_eq!(mismatch_detail(&c), "924 of 4084 compared pixels differ (value 924)");
        c.element_reads = Some(ElementReads {
            outside_spec: "VUID-X".into(),
            neither: 924,
            ..Default::default()
        });
        let d = mismatch_detail(&c);
        assert!(
            d.contains("VUID-X") && d.contains("924 pixels read an element no active lane"),
            "{d}"
        );
        assert!(!d.contains('{'), "no debug output: {d}");
    }

    /// A report of an older rtprobe said the per-field map in debug form; read back, the counts
    /// come from the comparison in words and the notes after them stay. The twin: a detail that
    /// does not begin with the comparison's own counts (here, other counts) is left alone.
    #[test]
    fn an_old_debug_form_detail_is_said_in_words_from_its_comparison() {
        let mut c = Comparison { compared: 4087, mismatched_pixels: 926, ..Default::default() };
        c.by_field.insert("value".into(), 926);
        let old = r#"926 of 4087 compared pixels differ ({"value": 926}); a note"#;
        assert_eq!(
            detail_in_words(old, &c),
            "926 of 4087 compared pixels differ (value 926); a note"
        );
        let other = r#"925 of 4087 compared pixels differ ({"value": 925})"#;
        assert_eq!(detail_in_words(other, &c), other);
        let words = "926 of 4087 compared pixels differ (value 926)";
        assert_eq!(detail_in_words(words, &c), words);
    }

    #[test]
    fn a_binding_mapping_names_its_members_and_its_sampler_fields() {
        let m = BindingMapping {
            descriptor_set: 0,
            first_binding: 2,
            binding_count: 1,
            resource_mask: "VK_SPIRV_RESOURCE_TYPE_ALL_EXT".into(),
            source: "VK_DESCRIPTOR_MAPPING_SOURCE_HEAP_WITH_CONSTANT_OFFSET_EXT".into(),
            source_member: "constantOffset".into(),
            fields: [
                ("heapOffset", "192"),
                ("pEmbeddedSampler", "NULL"),
                ("samplerHeapOffset", "0"),
            ]
            .iter()
            .map(|(n, v)| (n.to_string(), v.to_string()))
            .collect(),
        };
        assert_eq!(m.text(), "{ descriptorSet 0, firstBinding 2, bindingCount 1, resourceMask VK_SPIRV_RESOURCE_TYPE_ALL_EXT, source VK_DESCRIPTOR_MAPPING_SOURCE_HEAP_WITH_CONSTANT_OFFSET_EXT, sourceData.constantOffset { heapOffset 192, pEmbeddedSampler NULL, samplerHeapOffset 0 } }");
        assert_eq!(m.sampler_fields(), "pEmbeddedSampler NULL, samplerHeapOffset 0");
    }
}
