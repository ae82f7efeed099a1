//! An Amber script's `EXPECT`s against a records buffer, read the way Amber's verifier reads them
//! (`src/verifier.cc`, `Verifier::ProbeSSBO`): the buffer's `STRUCT` members in order, each
//! value compared with the member at its offset — integers as integers, floats as the f32 the
//! decimal parses to — within the EXPECT's first `TOLERANCE` (absolute), or exactly without one;
//! an offset must be a multiple of the struct's size and the values must fit in the buffer. rtprobe
//! cannot run Amber where it writes the scripts (Amber is not packaged in Debian); this runs a
//! script's expectations against the records rtprobe's own worker read back for the same cell
//! (`run --dump DIR` writes them to `DIR/<cell id>/records.bin`).

/// What a script's expectations cannot be read as.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CheckError {
    /// A line that does not parse (`line`: 1-based).
    #[error("line {line}: {what}")]
    Syntax { line: usize, what: String },
    #[error("no STRUCT {0} in the script")]
    NoStruct(String),
    #[error("no BUFFER {0} with a STRUCT type in the script")]
    NoBuffer(String),
}

/// A scalar of the records struct: its byte offset in a record and whether it is a float.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Scalar {
    offset: usize,
    float: bool,
}

/// The scalars of `STRUCT name` (members with explicit `OFFSET`s), and its stride.
fn struct_layout(script: &str, name: &str) -> Result<(Vec<Scalar>, usize), CheckError> {
    let mut lines = script.lines().enumerate();
    let header = format!("STRUCT {name} STRIDE ");
    let (_, head) = lines
        .find(|(_, l)| l.starts_with(&header))
        .ok_or_else(|| CheckError::NoStruct(name.into()))?;
    let stride =
        head[header.len()..].trim().parse().map_err(|_| CheckError::NoStruct(name.into()))?;
    let mut scalars = Vec::new();
    for (k, l) in lines {
        let w: Vec<&str> = l.split_whitespace().collect();
        let syntax = |what: &str| CheckError::Syntax { line: k + 1, what: what.into() };
        match w.as_slice() {
            ["END"] => return Ok((scalars, stride)),
            [ty, _, "OFFSET", off] => {
                let off: usize = off.parse().map_err(|_| syntax("OFFSET is not a number"))?;
                let (n, float) = match *ty {
                    "uint32" => (1, false),
                    "float" => (1, true),
                    "vec2<float>" => (2, true),
                    "vec4<float>" => (4, true),
                    _ => return Err(syntax("a member type this checker does not read")),
                };
                scalars.extend((0..n).map(|c| Scalar { offset: off + 4 * c, float }));
            }
            _ => return Err(syntax("not a STRUCT member with an OFFSET")),
        }
    }
    Err(CheckError::NoStruct(name.into()))
}

/// `BUFFER name DATA_TYPE type STD430 SIZE n …`: the type and the element count.
fn buffer_decl(script: &str, name: &str) -> Result<(String, usize), CheckError> {
    let head = format!("BUFFER {name} DATA_TYPE ");
    script
        .lines()
        .find_map(|l| {
            let w: Vec<&str> = l.strip_prefix(&head)?.split_whitespace().collect();
            let size = w.iter().position(|x| *x == "SIZE").and_then(|k| w.get(k + 1))?;
            Some((w.first()?.to_string(), size.parse().ok()?))
        })
        .ok_or_else(|| CheckError::NoBuffer(name.into()))
}

/// One EXPECT: its line, byte offset, tolerance (None: exact) and values.
struct Expect<'a> {
    line: usize,
    offset: usize,
    tolerance: Option<f64>,
    values: Vec<&'a str>,
}

fn parse_expect<'a>(
    line: usize,
    l: &'a str,
    buffer: &str,
) -> Result<Option<Expect<'a>>, CheckError> {
    let w: Vec<&str> = l.split_whitespace().collect();
    if w.first() != Some(&"EXPECT") || w.get(1) != Some(&buffer) {
        return Ok(None);
    }
    let syntax = |what: &str| CheckError::Syntax { line, what: what.into() };
    if w.get(2) != Some(&"IDX") {
        return Err(syntax("EXPECT without IDX"));
    }
    let offset =
        w.get(3).and_then(|x| x.parse().ok()).ok_or_else(|| syntax("IDX is not a number"))?;
    let (tolerance, rest) = match w.get(4) {
        Some(&"TOLERANCE") => {
            let t = w.get(5).ok_or_else(|| syntax("TOLERANCE without a value"))?;
            if t.ends_with('%') {
                return Err(syntax("a percent TOLERANCE, which rtprobe does not write"));
            }
            (Some(t.parse().map_err(|_| syntax("TOLERANCE is not a number"))?), &w[6..])
        }
        _ => (None, &w[4..]),
    };
    if rest.first() != Some(&"EQ") {
        return Err(syntax("only EQ comparisons are read"));
    }
    Ok(Some(Expect { line, offset, tolerance, values: rest[1..].to_vec() }))
}

/// Amber's `IsEqualWithTolerance` with an absolute tolerance (NaN equals only NaN).
fn within(actual: f64, expected: f64, tolerance: f64) -> bool {
    if actual.is_nan() || expected.is_nan() {
        return actual.is_nan() == expected.is_nan();
    }
    (actual - expected).abs() <= tolerance
}

/// Why one value of an EXPECT fails against `bytes`, or `None`.
fn value_fails(s: Scalar, at: usize, text: &str, tol: Option<f64>, bytes: &[u8]) -> Option<String> {
    let word = u32::from_le_bytes(bytes[at..at + 4].try_into().ok()?);
    if s.float {
        let actual = f32::from_bits(word) as f64;
        let Ok(e) = text.parse::<f64>() else { return Some(format!("{text:?} is not a float")) };
        let expected = e as f32 as f64;
        let ok = match tol {
            Some(t) => within(actual, expected, t),
            None => actual == expected || (actual.is_nan() && expected.is_nan()),
        };
        (!ok).then(|| format!("{actual} == {expected}"))
    } else {
        let Ok(expected) = text.parse::<u64>() else {
            return Some(format!("{text:?} is not an integer"));
        };
        let ok = match tol {
            Some(t) => within(word as f64, expected as f64, t),
            None => word as u64 == expected,
        };
        (!ok).then(|| format!("{word} == {expected}"))
    }
}

/// Every `EXPECT buffer …` of `script` against `bytes` (the buffer's contents): the failures, as
/// Amber would report them (`line N: … at index i`), and the number of EXPECTs read.
pub fn check(script: &str, buffer: &str, bytes: &[u8]) -> Result<(Vec<String>, usize), CheckError> {
    let (ty, elements) = buffer_decl(script, buffer)?;
    let (scalars, stride) = struct_layout(script, &ty)?;
    let size = elements * stride;
    let (mut failures, mut read) = (Vec::new(), 0);
    for (k, l) in script.lines().enumerate() {
        let Some(e) = parse_expect(k + 1, l, buffer)? else { continue };
        read += 1;
        let records = e.values.len().div_ceil(scalars.len()).max(1);
        if e.offset % stride != 0 || e.offset + records * stride > size.min(bytes.len()) {
            failures.push(format!(
                "line {}: offset {} is not a record inside the buffer",
                e.line, e.offset
            ));
            continue;
        }
        for (i, v) in e.values.iter().enumerate() {
            let s = scalars[i % scalars.len()];
            let at = e.offset + (i / scalars.len()) * stride + s.offset;
            if let Some(why) = value_fails(s, at, v, e.tolerance, bytes) {
                failures.push(format!("line {}: Verifier failed: {why}, at index {i}", e.line));
            }
        }
    }
    Ok((failures, read))
}
