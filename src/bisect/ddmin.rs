//! Zeller & Hildebrandt's ddmin ("Simplifying and Isolating Failure-Inducing Input", 2002) over
//! any list: the 1-minimal sublist for which a monotone test still holds. Bisection uses it over
//! the terms of a conjunction (a sublist of terms is a *wider* conjunction; the test is "it still
//! contains no passing cell"), so the result is a conjunction from which no single term can be
//! dropped.

/// A 1-minimal sublist of `items` (order kept) for which `test` holds, given that it holds for
/// `items`. The empty list is tried first. `test` is called on sublists only; callers memoize.
pub fn ddmin<T: Clone>(items: &[T], test: &mut dyn FnMut(&[T]) -> bool) -> Vec<T> {
    if test(&[]) {
        return vec![];
    }
    let mut c: Vec<T> = items.to_vec();
    let mut n = 2usize;
    while c.len() >= 2 {
        let chunks = split(&c, n);
        // Reduce to a subset.
        if let Some(ch) = chunks.iter().find(|ch| test(ch)) {
            c = ch.clone();
            n = 2;
            continue;
        }
        // Reduce to a complement.
        let complement = |i: usize| -> Vec<T> {
            chunks
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .flat_map(|(_, ch)| ch.iter().cloned())
                .collect()
        };
        if chunks.len() > 2 {
            if let Some(co) = (0..chunks.len()).map(complement).find(|co| test(co)) {
                c = co;
                n = (n - 1).max(2);
                continue;
            }
        }
        if n >= c.len() {
            break;
        }
        n = (2 * n).min(c.len());
    }
    c
}

/// `c` in `n` contiguous chunks of nearly equal size.
fn split<T: Clone>(c: &[T], n: usize) -> Vec<Vec<T>> {
    let n = n.min(c.len()).max(1);
    let mut out = Vec::with_capacity(n);
    let mut start = 0;
    for i in 0..n {
        let end = start + (c.len() - start) / (n - i);
        out.push(c[start..end].to_vec());
        start = end;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_needed_items_with_few_tests() {
        // The test holds when the sublist keeps items 3 and 7.
        let items: Vec<u32> = (0..10).collect();
        let mut calls = 0;
        let r = ddmin(&items, &mut |s| {
            calls += 1;
            s.contains(&3) && s.contains(&7)
        });
        assert_eq!(r, vec![3, 7]);
        assert!(calls < 40, "{calls} tests");
        // Nothing needed: the empty list.
        assert!(ddmin(&items, &mut |_| true).is_empty());
        // Everything needed.
        assert_eq!(ddmin(&[1, 2, 3], &mut |s: &[i32]| s.len() == 3), vec![1, 2, 3]);
    }

    #[test]
    fn result_is_one_minimal() {
        // Holds when at least two of {1, 4, 6} are kept: any 2-subset is 1-minimal.
        let items: Vec<u32> = (0..8).collect();
        let ok = |s: &[u32]| [1, 4, 6].iter().filter(|x| s.contains(x)).count() >= 2;
        let r = ddmin(&items, &mut |s| ok(s));
        assert!(ok(&r));
        for i in 0..r.len() {
            let mut less = r.clone();
            less.remove(i);
            assert!(!ok(&less), "{r:?} is not 1-minimal");
        }
    }

    #[test]
    fn split_covers_everything_in_order() {
        assert_eq!(split(&[1, 2, 3, 4, 5], 2), vec![vec![1, 2], vec![3, 4, 5]]);
        assert_eq!(split(&[1, 2], 5), vec![vec![1], vec![2]]);
    }
}
