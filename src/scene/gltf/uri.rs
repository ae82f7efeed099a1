//! The bytes behind a glTF URI (glTF 2.0, "URIs"): a `data:` URI with base64 data, a path relative
//! to the file (percent-decoded, as the spec's URI references are), or a `file:` URI. Other
//! schemes (`http:`) are refused: rtprobe reads local files only.
//!
//! This, with [`super::pixels`], replaces the `gltf` crate's `import` feature, which pulls the
//! `image` crate and its colour management (`moxcms`, `pxfm`): some 60 s of a fresh build's CPU
//! (reports/ci/costs.md) for the two formats glTF 2.0 allows, which `png` and `zune-jpeg` decode.
use base64::Engine as _;
use std::path::{Path, PathBuf};

/// What `uri` (relative to `base`, the scene's folder) holds, or why the `what` (an image, a
/// buffer) cannot be read (one line, saying what to do).
pub(super) fn read(base: &Path, uri: &str, what: &str) -> Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, data) = rest.split_once(";base64,").ok_or(
            "a data URI without \";base64,\": give its data base64-encoded, or as a file beside the scene",
        )?;
        return base64::engine::general_purpose::STANDARD
            .decode(data)
            .map_err(|e| format!("its data URI is not base64 ({e}); export the scene again"));
    }
    let path = path_of(base, uri)?;
    std::fs::read(&path).map_err(|e| {
        format!(
            "cannot read the {what} file {}: {e}; put the {what}s beside the .gltf file (URIs are relative to it) or fix the URI",
            path.display()
        )
    })
}

/// The local path of a file URI or a relative URI reference.
fn path_of(base: &Path, uri: &str) -> Result<PathBuf, String> {
    if let Some(p) = uri.strip_prefix("file://").or_else(|| uri.strip_prefix("file:")) {
        return Ok(PathBuf::from(decoded(p)?));
    }
    if uri.contains("://") {
        return Err(format!(
            "URI {uri} is not a local file; download it beside the scene and give its relative path"
        ));
    }
    Ok(base.join(lexical(&decoded(uri)?)))
}

/// A relative URI reference's path with its `.` and `..` segments resolved as text (RFC 3986,
/// 5.2.4), as a URI's are: `sub/../a.png` is `a.png` whether or not `sub/` exists.
fn lexical(path: &str) -> PathBuf {
    let mut out: Vec<&str> = Vec::new();
    for seg in path.split('/') {
        match seg {
            "." | "" => {}
            ".." => {
                out.pop();
            }
            s => out.push(s),
        }
    }
    out.iter().collect()
}

fn decoded(s: &str) -> Result<String, String> {
    urlencoding::decode(s)
        .map(|c| c.into_owned())
        .map_err(|_| format!("URI {s} does not percent-decode to UTF-8; rename the file"))
}

#[cfg(test)]
mod tests {
    use super::read;
    use std::path::Path;

    #[test]
    fn data_uris_decode_and_bad_ones_say_why() {
        assert_eq!(
            read(Path::new("."), "data:application/octet-stream;base64,AAEC", "buffer").unwrap(),
            [0, 1, 2]
        );
        assert!(read(Path::new("."), "data:text/plain,hi", "buffer")
            .unwrap_err()
            .contains("base64"));
        assert!(read(Path::new("."), "data:x;base64,@@@", "buffer")
            .unwrap_err()
            .contains("not base64"));
    }

    #[test]
    fn relative_paths_are_percent_decoded_and_remote_ones_refused() {
        let d = crate::tempdir::tempdir().unwrap();
        std::fs::write(d.path().join("a b.bin"), [7u8; 3]).unwrap();
        assert_eq!(read(d.path(), "a%20b.bin", "buffer").unwrap(), [7, 7, 7]);
        assert_eq!(read(d.path(), "./gone/../a%20b.bin", "buffer").unwrap(), [7, 7, 7]);
        let missing = read(d.path(), "gone.bin", "buffer").unwrap_err();
        assert!(
            missing.contains("gone.bin")
                && missing.contains("put the buffers beside the .gltf file"),
            "{missing}"
        );
        assert!(read(d.path(), "https://example.com/a.bin", "buffer")
            .unwrap_err()
            .contains("not a local file"));
    }
}
