//! Words for people: counts with their noun's plural, and the nearest known word to a mistyped one
//! (`closesthit` → `closest_hit`) for error messages.

/// `n` and its noun, plural (an `s` added) unless `n` is 1: `1 cell`, `0 cells`, `6 cells`.
pub fn plural(n: usize, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

/// Edit distance (insertions, deletions, substitutions) between `a` and `b`, by characters.
fn distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diag = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let next = (row[j + 1] + 1).min(row[j] + 1).min(diag + usize::from(ca != *cb));
            diag = row[j + 1];
            row[j + 1] = next;
        }
    }
    row[b.len()]
}

/// The candidate closest to `word` (case-insensitive), when it is close enough to be a typo: at
/// most a third of its length away (at least 1, at most 3 edits); the first of equals wins.
pub fn nearest<'a>(word: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    let w = word.to_ascii_lowercase();
    let limit = (w.chars().count() / 3).clamp(1, 3);
    candidates
        .into_iter()
        .map(|c| (distance(&w, &c.to_ascii_lowercase()), c))
        .filter(|(d, _)| *d <= limit)
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plurals_agree_with_their_count() {
        assert_eq!(plural(1, "cell"), "1 cell");
        assert_eq!(plural(0, "cell"), "0 cells");
        assert_eq!(plural(21, "cell"), "21 cells");
    }

    #[test]
    fn a_typo_finds_its_word_and_nonsense_finds_none() {
        let stages = ["raygen", "closest_hit", "any_hit", "miss", "intersection"];
        assert_eq!(nearest("closesthit", stages), Some("closest_hit"));
        assert_eq!(nearest("ClosestHit", stages), Some("closest_hit"));
        assert_eq!(nearest("raygne", stages), Some("raygen"));
        assert_eq!(nearest("mis", stages), Some("miss"));
        assert_eq!(nearest("vertex", stages), None);
        assert_eq!(nearest("x", stages), None);
        assert_eq!(distance("kitten", "sitting"), 3);
        assert_eq!(distance("", "abc"), 3);
    }
}
