//! Why `--filter`s leave no cell of the matrix to plan, in one sentence: a filter that matches no
//! cell alone (a term no cell has, or two terms no cell has together), or two filters with no
//! cell in common (repeated `--filter`s must all match). `run` fails with it instead of passing
//! an empty plan.
use super::plan::all_cells;
use crate::model::{Cell, Filter, PatchMode};

/// The cells the filters choose among: the matrix, and each cell's workaround variants when
/// `patches` plans them (`--patches all`).
fn universe(patches: PatchMode) -> Vec<Cell> {
    let (cells, _) = all_cells();
    if patches != PatchMode::All {
        return cells;
    }
    cells
        .iter()
        .flat_map(|c| {
            std::iter::once(*c)
                .chain(c.applicable_patches().into_iter().map(|p| Cell { patch: Some(p), ..*c }))
        })
        .collect()
}

fn any(cells: &[Cell], filters: &[&Filter]) -> bool {
    cells.iter().any(|c| filters.iter().all(|f| f.matches(c)))
}

/// Why no cell matches `f` alone (`None`: some cell does).
fn why_filter(cells: &[Cell], f: &Filter, patches: PatchMode) -> Option<String> {
    if any(cells, &[f]) {
        return None;
    }
    let terms = f.split_terms();
    if let Some(t) = terms.iter().find(|t| !any(cells, &[t])) {
        let note = if t.terms[0].0 == "patch" && patches != PatchMode::All {
            " (workaround variants are planned cells only with --patches all)"
        } else {
            ""
        };
        return Some(format!("no cell of the matrix has {}{note}", t.text()));
    }
    for (i, a) in terms.iter().enumerate() {
        if let Some(b) = terms[i + 1..].iter().find(|b| !any(cells, &[a, b])) {
            return Some(format!(
                "no cell of the matrix has both {} and {} (`rtprobe run --help` says where each axis applies)",
                a.text(),
                b.text()
            ));
        }
    }
    Some(format!("no cell of the matrix has all of {}", f.text()))
}

/// Why `filters` plan nothing (`None`: they leave some cell).
pub fn why_empty(filters: &[Filter], patches: PatchMode) -> Option<String> {
    let cells = universe(patches);
    let all: Vec<&Filter> = filters.iter().collect();
    if any(&cells, &all) {
        return None;
    }
    for f in filters {
        if let Some(why) = why_filter(&cells, f, patches) {
            return Some(format!("--filter '{}' matches no cell: {why}", f.text()));
        }
    }
    for (i, a) in filters.iter().enumerate() {
        if let Some(b) = filters[i + 1..].iter().find(|b| !any(&cells, &[a, b])) {
            return Some(format!(
                "--filter '{}' and --filter '{}' have no cell in common: repeated --filters must all match; for alternatives give one filter with values joined by `|` (axis=a|b)",
                a.text(),
                b.text()
            ));
        }
    }
    Some("the --filters have no cell in common: repeated --filters must all match".into())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn filters(fs: &[&str]) -> Vec<Filter> {
        fs.iter().map(|f| Filter::parse(f).unwrap()).collect()
    }

    #[test]
    fn filters_that_leave_cells_have_no_reason() {
        assert_eq!(why_empty(&filters(&["stage=closest_hit|raygen"]), PatchMode::Faults), None);
        assert_eq!(why_empty(&[], PatchMode::Faults), None);
    }

    #[test]
    fn two_terms_no_cell_has_together_are_named() {
        let why = why_empty(
            &filters(&["resource=storage_buffer,as_access=descriptor"]),
            PatchMode::Faults,
        )
        .unwrap();
        assert!(why.contains("both resource=storage_buffer and as_access=descriptor"), "{why}");
    }

    #[test]
    fn repeated_filters_without_a_common_cell_say_how_they_combine() {
        let why =
            why_empty(&filters(&["stage=closest_hit", "stage=raygen"]), PatchMode::Faults).unwrap();
        assert!(why.contains("must all match") && why.contains("axis=a|b"), "{why}");
    }

    #[test]
    fn a_patch_term_without_patches_all_says_so() {
        let f = filters(&["patch=pin-index"]);
        let why = why_empty(&f, PatchMode::Faults).unwrap();
        assert!(why.contains("--patches all"), "{why}");
        assert_eq!(why_empty(&f, PatchMode::All), None);
    }
}
