//! Where the descriptors sit in the resource heap: records and scene TLAS in slots of the largest
//! buffer / image descriptor, the probed array at its own stride (first for `direct` cells, after
//! the records and TLAS for mapped ones).

pub(super) fn align(x: u64, a: u64) -> u64 {
    x.div_ceil(a.max(1)) * a.max(1)
}

/// Where the descriptors sit in the resource heap (bytes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HeapLayout {
    pub records: u32,
    pub tlas: u32,
    /// The probed array's element 0, and its stride (the descriptor size of its type).
    pub probe: u32,
    pub probe_stride: u32,
}

impl HeapLayout {
    /// `slot`: bytes per records / TLAS slot; `probe_stride`: the probed type's descriptor size;
    /// `probe_count`: elements of the probed array; `direct`: the array first (see the module doc).
    pub fn new(slot: u32, probe_stride: u32, probe_count: u32, direct: bool) -> HeapLayout {
        if direct {
            let records = align((probe_count * probe_stride) as u64, slot as u64) as u32;
            HeapLayout { records, tlas: records + slot, probe: 0, probe_stride }
        } else {
            // After records and TLAS, one unused descriptor, so an index off by one reads zeros.
            let index = (2 * slot).div_ceil(probe_stride.max(1)) + 1;
            HeapLayout { records: 0, tlas: slot, probe: index * probe_stride, probe_stride }
        }
    }

    /// The heap index of the probed array's element 0 in units of its stride (what push data or
    /// the shader record holds for the index-sourced mappings).
    pub fn probe_index(&self) -> u32 {
        self.probe / self.probe_stride.max(1)
    }

    pub(super) fn offset(&self, binding: u32, element: usize) -> usize {
        match binding {
            0 => self.records as usize,
            1 => self.tlas as usize,
            _ => self.probe as usize + element * self.probe_stride as usize,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_keep_descriptors_apart_and_index_sources_agree() {
        for direct in [false, true] {
            for (slot, stride) in [(64, 16), (64, 64), (64, 32), (256, 48)] {
                let l = HeapLayout::new(slot, stride, 17, direct);
                let probe_end = l.probe + 17 * stride;
                // records, TLAS and the probed array do not overlap
                assert!(l.records + slot <= l.tlas || l.tlas + slot <= l.records);
                for start in [l.records, l.tlas] {
                    assert!(start + slot <= l.probe || probe_end <= start, "{l:?}");
                }
                // an index-sourced mapping (index × stride) lands exactly on the array
                assert_eq!(l.probe_index() * stride, l.probe, "{l:?}");
                assert_eq!(direct, l.probe == 0);
            }
        }
    }
}
