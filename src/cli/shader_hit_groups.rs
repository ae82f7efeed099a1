//! `run --shader --hit-group K=FILE[,FILE…]` ([`parse`]): the ray type (SBT record offset) each
//! named hit shader serves, by the input's name, where its payload cannot say it
//! (`harness::ray_types`).
use super::exit::{self, coded};
use super::patch_inputs::Input;
use anyhow::Result;
use std::collections::BTreeMap;
use std::path::Path;

/// Whether `file` (as given to `--hit-group`) names input `i`: its path as given, or its file
/// name.
fn names(file: &str, i: &Input) -> bool {
    let f = Path::new(file);
    f == i.path || (f.components().count() == 1 && i.path.file_name() == Some(f.as_os_str()))
}

/// Each `K=FILE[,FILE…]` of `values` over `inputs`: input name → ray type. A malformed value, a
/// file that is none of the inputs, or one given two ray types is refused in one line.
pub fn parse(values: &[String], inputs: &[Input]) -> Result<BTreeMap<String, u32>> {
    let usage = |v: &str, why: &str| {
        coded(exit::USAGE, format!("--hit-group {v}: {why}; give K=FILE[,FILE…], K the SBT record offset the rays of that ray type trace with"))
    };
    let mut out = BTreeMap::new();
    for v in values {
        let Some((k, files)) = v.split_once('=') else { return Err(usage(v, "no `=`")) };
        let k: u32 = k.trim().parse().map_err(|_| usage(v, "K is not a number"))?;
        for file in files.split(',').map(str::trim) {
            let Some(i) = inputs.iter().find(|i| names(file, i)) else {
                return Err(usage(v, &format!("{file} is none of the --shader files")));
            };
            if out.insert(i.name.clone(), k).is_some_and(|was| was != k) {
                return Err(usage(v, &format!("{file} is given two ray types: a module serves one here; give a copy under another file name for the second")));
            }
        }
    }
    Ok(out)
}
