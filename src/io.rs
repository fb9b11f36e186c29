//! Reading model files (URDF, joint-parameter TOML) as text: regular files only, of bounded size,
//! decoded from what XML allows.
//!
//! A directory is [`Error::IsADirectory`]; a FIFO, socket or device is refused instead of being
//! read (a FIFO would block for ever); a file over [`MAX_FILE_BYTES`] is refused before it is
//! read. Text is UTF-8 (a byte-order mark is skipped); a UTF-16 file with its byte-order mark, or
//! a file whose XML declaration says `ISO-8859-1`/`Latin-1`, is decoded as such. Anything else
//! that is not UTF-8 is an [`Error::Malformed`] saying so, with the offset of the first bad byte.
//!
//! ```
//! let latin1 = b"<?xml version='1.0' encoding='ISO-8859-1'?><robot name='Gr\xfc\xdfe'/>";
//! assert!(orbitflex::io::decode(latin1).unwrap().ends_with("name='Grüße'/>"));
//! assert!(orbitflex::io::decode(b"caf\xe9").unwrap_err().contains("not UTF-8"));
//! ```

use crate::error::{Error, Result};
use std::path::Path;

/// The largest model file read, in bytes (64 MiB; a URDF of 10⁵ links is about 30 MB).
pub const MAX_FILE_BYTES: u64 = 64 << 20;

/// Reads the file at `path` as text; `format` (e.g. `"URDF"`) names it in messages.
pub fn read_text(path: &Path, format: &'static str) -> Result<String> {
    let not_found = |e: std::io::Error| Error::FileNotFound {
        path: path.to_path_buf(),
        reason: e.to_string(),
    };
    let metadata = std::fs::metadata(path).map_err(not_found)?;
    if metadata.is_dir() {
        return Err(Error::IsADirectory {
            path: path.to_path_buf(),
        });
    }
    if !metadata.is_file() {
        return Err(Error::InvalidArgument {
            what: path.display().to_string(),
            message: format!(
                "not a regular file (a FIFO, socket or device); expected a {format} file"
            ),
        });
    }
    if metadata.len() > MAX_FILE_BYTES {
        return Err(Error::Malformed {
            source_name: path.display().to_string(),
            format,
            message: format!(
                "the file has {} bytes, more than the {MAX_FILE_BYTES} read",
                metadata.len()
            ),
        });
    }
    let bytes = std::fs::read(path).map_err(not_found)?;
    decode(&bytes).map_err(|message| Error::Malformed {
        source_name: path.display().to_string(),
        format,
        message,
    })
}

/// Text from bytes: UTF-8 (with or without a byte-order mark), UTF-16 with a byte-order mark,
/// or Latin-1 when the XML declaration says so.
pub fn decode(bytes: &[u8]) -> std::result::Result<String, String> {
    if let Some(rest) = bytes.strip_prefix(b"\xEF\xBB\xBF") {
        return utf8(rest);
    }
    let utf16 = |rest: &[u8], from: fn([u8; 2]) -> u16| {
        let units = rest.chunks_exact(2).map(|c| from([c[0], c[1]]));
        char::decode_utf16(units)
            .collect::<std::result::Result<String, _>>()
            .map_err(|e| format!("not valid UTF-16 ({e})"))
    };
    if let Some(rest) = bytes.strip_prefix(b"\xFF\xFE") {
        return utf16(rest, u16::from_le_bytes);
    }
    if let Some(rest) = bytes.strip_prefix(b"\xFE\xFF") {
        return utf16(rest, u16::from_be_bytes);
    }
    match std::str::from_utf8(bytes) {
        Ok(text) => Ok(text.to_string()),
        Err(e) => match declared_encoding(bytes) {
            Some(enc) if is_latin1(&enc) => Ok(bytes.iter().map(|&b| b as char).collect()),
            Some(enc) => Err(format!(
                "the file declares encoding=\"{enc}\", which orbitflex does not read, and is not \
                 UTF-8 (byte {}); save it as UTF-8",
                e.valid_up_to()
            )),
            None => Err(format!(
                "not UTF-8 text (invalid byte at offset {}); save the file as UTF-8",
                e.valid_up_to()
            )),
        },
    }
}

fn utf8(bytes: &[u8]) -> std::result::Result<String, String> {
    std::str::from_utf8(bytes).map(str::to_string).map_err(|e| {
        format!(
            "not UTF-8 text (invalid byte at offset {})",
            e.valid_up_to()
        )
    })
}

/// The `encoding` of an XML declaration `<?xml … encoding="…"?>` at the start of the bytes.
fn declared_encoding(bytes: &[u8]) -> Option<String> {
    let head = &bytes[..bytes.len().min(200)];
    let head: String = head.iter().map(|&b| b as char).collect();
    let decl = head.trim_start().strip_prefix("<?xml")?;
    let decl = &decl[..decl.find("?>")?];
    let at = decl.find("encoding")?;
    let rest = decl[at + "encoding".len()..]
        .trim_start()
        .strip_prefix('=')?;
    let rest = rest.trim_start();
    let quote = rest.chars().next().filter(|c| *c == '"' || *c == '\'')?;
    let value = &rest[1..];
    Some(value[..value.find(quote)?].to_string())
}

fn is_latin1(encoding: &str) -> bool {
    matches!(
        encoding.to_ascii_lowercase().as_str(),
        "iso-8859-1" | "iso8859-1" | "latin-1" | "latin1" | "l1" | "iso_8859-1"
    )
}

/// The memory available to new allocations, in bytes, where the system says (Linux:
/// `MemAvailable` in `/proc/meminfo`); `None` elsewhere.
pub fn available_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

#[cfg(test)]
mod tests {
    use super::decode;

    #[test]
    fn available_memory_is_known_on_linux() {
        if cfg!(target_os = "linux") {
            let bytes = super::available_memory().unwrap();
            assert!(bytes > 1 << 20, "{bytes}");
        }
    }

    #[test]
    fn decodes_what_xml_allows_and_names_what_it_does_not() {
        assert_eq!(decode("grüß".as_bytes()).unwrap(), "grüß");
        assert_eq!(decode(b"\xEF\xBB\xBFabc").unwrap(), "abc");
        let latin = b"<?xml version='1.0' encoding='ISO-8859-1'?><robot name='gr\xFC\xDF'/>";
        assert_eq!(
            decode(latin).unwrap(),
            "<?xml version='1.0' encoding='ISO-8859-1'?><robot name='grüß'/>"
        );
        let utf16: Vec<u8> = [0xFF, 0xFE]
            .into_iter()
            .chain("<r/>".encode_utf16().flat_map(u16::to_le_bytes))
            .collect();
        assert_eq!(decode(&utf16).unwrap(), "<r/>");
        let err = decode(b"<robot name='\xFF'/>").unwrap_err();
        assert!(
            err.contains("not UTF-8") && err.contains("offset 13"),
            "{err}"
        );
        let err =
            decode(b"<?xml version=\"1.0\" encoding=\"Shift_JIS\"?><r a='\x82\xA0'/>").unwrap_err();
        assert!(err.contains("Shift_JIS"), "{err}");
    }
}
