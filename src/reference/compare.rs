//! A cell's records against the reference's: per pixel the hit fields within their tolerances
//! (`T_REL_TOL`, `BARY_TOL`) and the probed value by its rule, with counts, worst errors, the
//! own/other/neither reads of an undefined index, and the first mismatches as examples.
use super::rules::{Expected, ValueRule, BARY_TOL, T_REL_TOL};
use crate::model::{Comparison, ElementReads, Mismatch, NO_NONUNIFORM_VUID};
use crate::probe::{Record, FLAG_HIT, FLAG_LANES, FLAG_PROBE};

/// The larger error, NaN when either is NaN (`f64::max` would drop it).
fn worst(acc: f64, e: f64) -> f64 {
    if acc.is_nan() || e.is_nan() {
        f64::NAN
    } else {
        acc.max(e)
    }
}

type Bad = Vec<(&'static str, String, String)>;

/// Integer and float fields a flag says were not written: their exact bits.
fn unset_fields_differ(bad: &mut Bad, fields: &[(&'static str, u32, u32)]) {
    for &(name, e, a) in fields {
        if e != a {
            bad.push((name, format!("{e:#x}"), format!("{a:#x}")));
        }
    }
}

fn compare_hit(c: &mut Comparison, bad: &mut Bad, r: &Record, a: &Record) {
    for (name, e, g) in [
        ("custom", r.custom, a.custom),
        ("instance_id", r.instance_id, a.instance_id),
        ("geometry", r.geometry, a.geometry),
        ("primitive", r.primitive, a.primitive),
    ] {
        if e != g {
            bad.push((name, e.to_string(), g.to_string()));
        }
    }
    let te = ((a.t as f64 - r.t as f64) / (r.t as f64).abs().max(1.0)).abs();
    c.worst_t_rel = worst(c.worst_t_rel, te);
    if te.is_nan() || te > T_REL_TOL {
        bad.push(("t", r.t.to_string(), a.t.to_string()));
    }
    let be = (0..2).map(|k| (a.bary[k] as f64 - r.bary[k] as f64).abs()).fold(0.0, worst);
    c.worst_bary = worst(c.worst_bary, be);
    if be.is_nan() || be > BARY_TOL {
        bad.push(("bary", format!("{:?}", r.bary), format!("{:?}", a.bary)));
    }
}

/// The lane words: consistent where the probe measured them (`FLAG_LANES`), else all zero.
fn compare_lanes(bad: &mut Bad, r: &Record, a: &Record, pixels: usize) {
    if r.flags & FLAG_LANES != 0 {
        if let Some(why) = super::lanes::inconsistency(a, pixels) {
            let words = format!(
                "lane {} leader {} mask {:#x} count {}",
                a.lane, a.leader, a.active_mask, a.active_count
            );
            bad.push(("lanes", format!("consistent lane words ({why})"), words));
        }
    } else {
        unset_fields_differ(
            bad,
            &[
                ("lanes", 0, a.lane),
                ("lanes", 0, a.leader),
                ("lanes", 0, a.active_mask),
                ("lanes", 0, a.active_count),
            ],
        );
    }
}

fn compare_probe(c: &mut Comparison, bad: &mut Bad, e: &Expected, a: &Record) {
    let r = &e.record;
    for (name, x, g) in [("slot", r.slot, a.slot), ("element", r.element, a.element)] {
        if x != g {
            bad.push((name, x.to_string(), g.to_string()));
        }
    }
    let own = r.value == a.value;
    let allowed = !own && e.rule.allows(a.value);
    if !allowed {
        let ve =
            r.value.iter().zip(a.value).map(|(x, y)| (*x as f64 - y as f64).abs()).fold(0.0, worst);
        c.worst_value = worst(c.worst_value, ve);
    }
    match e.rule {
        ValueRule::Exact => {
            if e.discriminating {
                *c.discrimination.get_or_insert(0.0) += 1.0;
            } else {
                c.discrimination.get_or_insert(0.0);
            }
        }
        ValueRule::AnyElement { .. } => {
            c.any_element_values += 1;
            let reads = c.element_reads.get_or_insert_with(|| ElementReads {
                outside_spec: NO_NONUNIFORM_VUID.into(),
                ..Default::default()
            });
            match (own, allowed) {
                (true, _) => reads.own += 1,
                (false, true) => reads.other += 1,
                (false, false) => reads.neither += 1,
            }
        }
    }
    if !own && !allowed {
        bad.push(("value", format!("{:?}", r.value), format!("{:?}", a.value)));
    }
}

pub fn compare(expected: &[Expected], actual: &[Record], width: u32) -> Comparison {
    let mut c = Comparison { pixels: expected.len(), ..Default::default() };
    let mut exact_probe_pixels = 0usize;
    for (i, (e, a)) in expected.iter().zip(actual).enumerate() {
        if e.ambiguous {
            c.ambiguous += 1;
            continue;
        }
        c.compared += 1;
        let r = &e.record;
        if r.flags & FLAG_PROBE != 0 {
            c.probe_checked += 1;
        }
        let mut bad: Bad = Vec::new();
        if r.flags != a.flags {
            bad.push(("flags", r.flags.to_string(), a.flags.to_string()));
        } else {
            if r.flags & FLAG_HIT != 0 {
                compare_hit(&mut c, &mut bad, r, a);
            } else {
                unset_fields_differ(
                    &mut bad,
                    &[
                        ("custom", r.custom, a.custom),
                        ("instance_id", r.instance_id, a.instance_id),
                        ("geometry", r.geometry, a.geometry),
                        ("primitive", r.primitive, a.primitive),
                        ("t", r.t.to_bits(), a.t.to_bits()),
                        ("bary", r.bary[0].to_bits(), a.bary[0].to_bits()),
                        ("bary", r.bary[1].to_bits(), a.bary[1].to_bits()),
                    ],
                );
            }
            compare_lanes(&mut bad, r, a, expected.len());
            if r.flags & FLAG_PROBE != 0 {
                if e.rule == ValueRule::Exact {
                    exact_probe_pixels += 1;
                }
                compare_probe(&mut c, &mut bad, e, a);
            } else {
                let mut fields = vec![("slot", r.slot, a.slot), ("element", r.element, a.element)];
                fields
                    .extend((0..4).map(|k| ("value", r.value[k].to_bits(), a.value[k].to_bits())));
                unset_fields_differ(&mut bad, &fields);
            }
        }
        if !bad.is_empty() {
            c.mismatched_pixels += 1;
            bad.dedup_by(|x, y| x.0 == y.0);
            for (field, exp, act) in bad {
                *c.by_field.entry(field.to_string()).or_default() += 1;
                if c.examples.len() < 8 {
                    let pixel = [i as u32 % width, i as u32 / width];
                    c.examples.push(Mismatch {
                        pixel,
                        field: field.into(),
                        expected: exp,
                        actual: act,
                    });
                }
            }
        }
    }
    if let Some(d) = c.discrimination.as_mut() {
        *d /= exact_probe_pixels as f64;
    }
    c
}
