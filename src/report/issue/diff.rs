//! Unified diffs for the issue (`diff -u`'s format: `---`/`+++` headers, `@@ -a,n +b,m @@` hunks
//! with three lines of context), from the passing sibling's shader to the failing one's. For
//! `spirv-dis` text, lines are matched with their numeric result ids masked
//! ([`mask_ids`]): two compiles of nearly the same GLSL number their unnamed ids differently
//! after the first change, and an unchanged instruction must show as context, not as a line
//! removed and added again. The lines shown are each side's own.

/// How lines are compared.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Match {
    /// Byte for byte (GLSL).
    Exact,
    /// With `%<digits>` ids masked (`spirv-dis` output).
    SpirvIds,
}

const CONTEXT: usize = 3;

/// `line` with every numeric id (`%` followed by digits only) replaced by `%_`.
pub fn mask_ids(line: &str) -> String {
    let mut out = String::with_capacity(line.len());
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        out.push(c);
        if c != '%' {
            continue;
        }
        let mut digits = String::new();
        while let Some(d) = chars.peek().copied().filter(char::is_ascii_digit) {
            digits.push(d);
            chars.next();
        }
        let named = chars.peek().is_some_and(|n| n.is_alphanumeric() || *n == '_');
        if digits.is_empty() || named {
            out.push_str(&digits);
        } else {
            out.push('_');
        }
    }
    out
}

/// One edit of the line sequence: a line of both (`Same(a, b)`), only of the old (`Del(a)`), only
/// of the new (`Add(b)`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Op {
    Same(usize, usize),
    Del(usize),
    Add(usize),
}

/// The edit script from `a` to `b` (longest common subsequence of their keys).
fn edits(a: &[String], b: &[String]) -> Vec<Op> {
    let (n, m) = (a.len(), b.len());
    let mut lcs = vec![0u32; (n + 1) * (m + 1)];
    let at = |i: usize, j: usize| i * (m + 1) + j;
    for i in (0..n).rev() {
        for j in (0..m).rev() {
            lcs[at(i, j)] = if a[i] == b[j] {
                lcs[at(i + 1, j + 1)] + 1
            } else {
                lcs[at(i + 1, j)].max(lcs[at(i, j + 1)])
            };
        }
    }
    let (mut i, mut j, mut ops) = (0, 0, Vec::new());
    while i < n || j < m {
        if i < n && j < m && a[i] == b[j] {
            ops.push(Op::Same(i, j));
            i += 1;
            j += 1;
        } else if i < n && (j == m || lcs[at(i + 1, j)] >= lcs[at(i, j + 1)]) {
            ops.push(Op::Del(i));
            i += 1;
        } else {
            ops.push(Op::Add(j));
            j += 1;
        }
    }
    ops
}

/// The unified diff from `old` (named `old_name`) to `new`, or `None` when no line differs.
pub fn unified(old: &str, new: &str, old_name: &str, new_name: &str, how: Match) -> Option<String> {
    let (a, b): (Vec<&str>, Vec<&str>) = (old.lines().collect(), new.lines().collect());
    let key = |l: &&str| match how {
        Match::Exact => l.to_string(),
        Match::SpirvIds => mask_ids(l),
    };
    let ops = edits(&a.iter().map(key).collect::<Vec<_>>(), &b.iter().map(key).collect::<Vec<_>>());
    let changed: Vec<usize> = ops
        .iter()
        .enumerate()
        .filter(|(_, o)| !matches!(o, Op::Same(..)))
        .map(|(k, _)| k)
        .collect();
    if changed.is_empty() {
        return None;
    }
    let mut out = format!("--- {old_name}\n+++ {new_name}\n");
    let mut k = 0;
    while k < changed.len() {
        // A hunk: from CONTEXT before the first change to CONTEXT after the last change that is
        // at most 2 × CONTEXT lines after the one before it.
        let first = changed[k];
        let mut last = first;
        while k + 1 < changed.len() && changed[k + 1] - last <= 2 * CONTEXT {
            k += 1;
            last = changed[k];
        }
        k += 1;
        let span = &ops[first.saturating_sub(CONTEXT)..(last + CONTEXT + 1).min(ops.len())];
        out += &hunk(span, &a, &b);
    }
    Some(out)
}

/// One hunk over `span` of the edit script: its `@@` header (1-based starts) and its lines.
fn hunk(span: &[Op], a: &[&str], b: &[&str]) -> String {
    let first_old = span.iter().find_map(|o| match o {
        Op::Same(i, _) | Op::Del(i) => Some(*i),
        Op::Add(_) => None,
    });
    let first_new = span.iter().find_map(|o| match o {
        Op::Same(_, j) | Op::Add(j) => Some(*j),
        Op::Del(_) => None,
    });
    let olds = span.iter().filter(|o| !matches!(o, Op::Add(_))).count();
    let news = span.iter().filter(|o| !matches!(o, Op::Del(_))).count();
    // A side with no line in the hunk is an empty file (context surrounds every change
    // otherwise): `diff -u` numbers it from 0.
    let (o, n) = (first_old.map_or(0, |i| i + 1), first_new.map_or(0, |j| j + 1));
    let mut s = format!("@@ -{o},{olds} +{n},{news} @@\n");
    for op in span {
        s += &match *op {
            Op::Same(_, j) => format!(" {}\n", b[j]),
            Op::Del(i) => format!("-{}\n", a[i]),
            Op::Add(j) => format!("+{}\n", b[j]),
        };
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(n: usize) -> String {
        (1..=n).map(|k| format!("line {k}\n")).collect()
    }

    #[test]
    fn a_changed_line_is_one_hunk_with_three_lines_of_context() {
        let old = lines(10);
        let new = old.replace("line 5\n", "line five\n");
        let d = unified(&old, &new, "a", "b", Match::Exact).unwrap();
        assert_eq!(
            d,
            "--- a\n+++ b\n@@ -2,7 +2,7 @@\n line 2\n line 3\n line 4\n-line 5\n+line five\n line 6\n line 7\n line 8\n"
        );
    }

    #[test]
    fn distant_changes_are_separate_hunks_and_near_ones_merge() {
        let old = lines(30);
        let new = old.replace("line 3\n", "").replace("line 25\n", "line 25\nnew\n");
        let d = unified(&old, &new, "a", "b", Match::Exact).unwrap();
        assert_eq!(d.matches("@@ -").count(), 2, "{d}");
        assert!(d.contains("@@ -1,6 +1,5 @@\n line 1\n line 2\n-line 3\n"), "{d}");
        assert!(d.contains("@@ -23,6 +22,7 @@\n"), "{d}");
        let near = old.replace("line 3\n", "").replace("line 8\n", "eight\n");
        let d = unified(&old, &near, "a", "b", Match::Exact).unwrap();
        assert_eq!(d.matches("@@ -").count(), 1, "{d}");
        assert!(unified(&old, &old, "a", "b", Match::Exact).is_none());
    }

    #[test]
    fn an_insertion_at_the_start_counts_from_line_zero_of_the_old_side() {
        let d = unified("x\n", "new\nx\n", "a", "b", Match::Exact).unwrap();
        assert!(d.contains("@@ -1,1 +1,2 @@\n+new\n x\n"), "{d}");
        let d = unified("", "new\n", "a", "b", Match::Exact).unwrap();
        assert!(d.contains("@@ -0,0 +1,1 @@\n+new\n"), "{d}");
    }

    /// The bug this replaced: unchanged SPIR-V declarations showed as removed and added because
    /// the later compile numbered its unnamed ids differently.
    #[test]
    fn spirv_lines_that_differ_only_in_numeric_ids_are_context() {
        let old = "OpMemberName %PushConstants 0 \"width\"\n%85 = OpBitcast %uint %84\n%86 = OpIAdd %uint %85 %int_3\nOpStore %probeSlot %86\n";
        let new = "OpMemberName %PushConstants 0 \"width\"\n%87 = OpBitcast %uint %86\n%88 = OpIAdd %uint %87 %104\nOpStore %probeSlot %88\n";
        let d = unified(old, new, "a", "b", Match::SpirvIds).unwrap();
        assert!(d.contains(" OpMemberName %PushConstants 0"), "{d}");
        assert!(d.contains(" %87 = OpBitcast %uint %86\n"), "shown as the new side's: {d}");
        assert!(
            d.contains("-%86 = OpIAdd %uint %85 %int_3\n+%88 = OpIAdd %uint %87 %104\n"),
            "{d}"
        );
        assert_eq!(d.lines().filter(|l| l.starts_with(['-', '+'])).count(), 4, "{d}");
        // Exact matching would see every numbered line change (the twin).
        let e = unified(old, new, "a", "b", Match::Exact).unwrap();
        assert!(e.lines().filter(|l| l.starts_with(['-', '+'])).count() > 4, "{e}");
    }

    #[test]
    fn only_numeric_ids_are_masked() {
        assert_eq!(
            mask_ids("%12 = OpLoad %v4float %probeValue"),
            "%_ = OpLoad %v4float %probeValue"
        );
        assert_eq!(mask_ids("%int_3 %3d %_ptr %5"), "%int_3 %3d %_ptr %_");
        assert_eq!(mask_ids("100% %"), "100% %");
    }
}
