//! The expected records as `EXPECT` lines, from rtprobe's CPU reference
//! (`reference::expected`): one per pixel whose record the reference can state exactly (not
//! ambiguous), over the record's first members — flags through `value`, or through `pad2` where
//! the spec leaves the read undefined — with one absolute tolerance per record:
//! `T_REL_TOL × max(|t|, 1)`, the reference's own bound on `t`. AmberScript applies an EXPECT's
//! first tolerance to every value, so integers below it compare exactly, the probed value's
//! distinct elements differ by at least 1, and barycentrics get the same bound as `t` (looser
//! than the reference's `BARY_TOL` where `t > 1`; the script says so).
use super::parts::{fmt_f32, RECORDS};
use crate::model::{Cell, LaneEvidence, SceneParams};
use crate::probe::spec::{ProbeSpec, ReadIndex};
use crate::probe::{Record, RECORD_SIZE};
use crate::reference::{self, T_REL_TOL};

/// Values an EXPECT gives: flags … pad2 (12), then the probed value's four.
pub const WITH_VALUE: usize = 16;
pub const WITHOUT_VALUE: usize = 12;

/// A float tolerance as AmberScript reads it back (always with a `.`).
fn fmt_f64(v: f64) -> String {
    let s = format!("{v:?}");
    if s.contains('.') {
        s
    } else {
        match s.find('e') {
            Some(e) => format!("{}.0{}", &s[..e], &s[e..]),
            None => format!("{s}.0"),
        }
    }
}

/// The first `n` values of `r` as an EXPECT writes them (uint32 members as integers, floats
/// with [`fmt_f32`]).
pub fn values(r: &Record, n: usize) -> Vec<String> {
    let u = |x: u32| x.to_string();
    let v = [
        u(r.flags),
        u(r.custom),
        u(r.instance_id),
        u(r.geometry),
        u(r.primitive),
        fmt_f32(r.t),
        fmt_f32(r.bary[0]),
        fmt_f32(r.bary[1]),
        u(r.slot),
        u(r.element),
        u(r.pad),
        u(r.pad2),
        fmt_f32(r.value[0]),
        fmt_f32(r.value[1]),
        fmt_f32(r.value[2]),
        fmt_f32(r.value[3]),
    ];
    v[..n].to_vec()
}

/// The tolerance of a record's EXPECT.
pub fn tolerance(r: &Record) -> f64 {
    T_REL_TOL * (r.t.abs() as f64).max(1.0)
}

/// The EXPECT lines of `cell` on `params`' scene, `lanes`: the probe records lane evidence (the
/// flags then carry `FLAG_LANES`).
pub fn expectations(cell: &Cell, params: &SceneParams, lanes: bool) -> String {
    let scene = crate::scene::Scene::build(params);
    let sref = reference::SceneReference::compute(&scene);
    let mut expected = reference::expected(cell, &scene, &sref);
    let evidence = if lanes { LaneEvidence::Supported } else { LaneEvidence::Absent };
    reference::expect_lanes(&mut expected, evidence);
    let undefined = ProbeSpec::of(cell).read == ReadIndex::Undefined;
    let n = if undefined { WITHOUT_VALUE } else { WITH_VALUE };
    let ambiguous = expected.iter().filter(|e| e.ambiguous).count();
    let mut s = format!(
        "# Expected records (rtprobe's f64 reference): EXPECT {RECORDS} IDX {RECORD_SIZE}*(x + y*width) TOLERANCE\n# 0.001*max(|t|, 1) EQ flags custom instanceId geometry primitive t bary.x bary.y slot element pad pad2{}.\n# The tolerance is rtprobe's on t; AmberScript applies it to every value, so integers and the probed value\n# compare exactly and barycentrics get the same bound (rtprobe's own is 0.001). {ambiguous} pixel(s) whose hit\n# is ambiguous within f32 error have no EXPECT; the lane words (lane, leader, activeMask, activeCount) have none.\n",
        if undefined { "" } else { " value.x value.y value.z value.w" }
    );
    if undefined {
        s += &format!("# No value in the EXPECTs: the index is dynamic without nonuniformEXT, so which element a lane reads is\n# undefined ({}); rtprobe accepts another lane's element there.\n", crate::model::NO_NONUNIFORM_VUID);
    }
    for (p, e) in expected.iter().enumerate().filter(|(_, e)| !e.ambiguous) {
        s += &format!(
            "EXPECT {RECORDS} IDX {} TOLERANCE {} EQ {}\n",
            p * RECORD_SIZE,
            fmt_f64(tolerance(&e.record)),
            values(&e.record, n).join(" ")
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tolerances_and_floats_keep_a_decimal_point() {
        assert_eq!(fmt_f64(0.001), "0.001");
        assert_eq!(fmt_f64(1.0), "1.0");
        assert_eq!(fmt_f64(1e-20), "1.0e-20");
        let r = Record { t: 12.5, ..Default::default() };
        assert!((tolerance(&r) - 0.0125).abs() < 1e-12);
        assert!((tolerance(&Record::default()) - 0.001).abs() < 1e-12);
    }
}
