//! History files on disk: append a record durably, read them back.
//!
//! An append writes the record and its newline with one `write`, then `fsync`s the file
//! (and the directory, when the append created the file) before it returns. Before the
//! record it makes sure the file ends in a newline: a line torn by a crash mid-write is
//! closed off, never glued onto. An append that fails part-way (a full disk) cuts the
//! file back to where it was, so nothing half-written stays behind it.

use std::fs;
use std::io::{self, Read, Seek, SeekFrom, Write};
use std::path::Path;

use super::{History, Record};

/// The default history file beside a params file: `DIR/STEM.history.jsonl`; empty when
/// `params_file` is empty.
pub fn default_path(params_file: &str) -> String {
    if params_file.is_empty() {
        return String::new();
    }
    let p = Path::new(params_file);
    let stem = p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let stem = if stem.is_empty() { "params".to_string() } else { stem };
    p.with_file_name(format!("{stem}.history.jsonl")).display().to_string()
}

/// A history file that exists but could not be read ([`read`]).
#[derive(Debug, thiserror::Error)]
#[error("{path}: cannot read: {source}")]
pub struct Unreadable {
    /// The file, as given.
    pub path: String,
    /// The system's reason (not `NotFound`: a missing file is an empty history).
    #[source]
    pub source: io::Error,
}

/// Read a history file. A file that does not exist is an empty history; one that cannot
/// be read is an error naming it. Lines that are not records are
/// skipped ([`History::parse`]).
pub fn read(path: &Path) -> Result<History, Unreadable> {
    let bytes = match fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(History::default()),
        Err(source) => return Err(Unreadable { path: path.display().to_string(), source }),
    };
    // A torn multi-byte character is in a torn line, which is skipped anyway.
    let text = String::from_utf8_lossy(&bytes);
    Ok(History::parse(&text, &path.display().to_string()))
}

/// Append `record` as one line to `path` (created if missing), durably: written and
/// `fsync`ed before this returns. Nothing of a failed append is left in the file.
pub fn append(path: &Path, record: &Record) -> io::Result<()> {
    let mut line = record.to_line();
    line.push('\n');
    let existed = path.exists();
    let mut f = fs::OpenOptions::new().read(true).append(true).create(true).open(path)?;
    let len = f.metadata()?.len();
    if len > 0 {
        let mut last = [0u8; 1];
        f.seek(SeekFrom::Start(len - 1))?;
        f.read_exact(&mut last)?;
        if last[0] != b'\n' {
            // A torn last line: close it off, the record starts on a line of its own.
            line.insert(0, '\n');
        }
    }
    let result = f.write_all(line.as_bytes()).and_then(|()| f.sync_all());
    if let Err(e) = result {
        // Cut off whatever part of the line went in; the file is as it was.
        let _ = f.set_len(len).and_then(|()| f.sync_all());
        return Err(e);
    }
    if !existed {
        let dir = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        fs::File::open(dir)?.sync_all()?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(scan_id: u32) -> Record {
        Record { node: "/t".into(), scan_id, ..Record::example() }
    }

    #[test]
    fn default_path_is_beside_the_params_file() {
        assert_eq!(default_path(""), "");
        assert_eq!(default_path("/var/lib/cell1/tracer.yaml"), "/var/lib/cell1/tracer.history.jsonl");
        assert_eq!(default_path("params.yaml"), "params.history.jsonl");
        assert_eq!(default_path("/x/.hidden"), "/x/.hidden.history.jsonl");
    }

    #[test]
    fn appends_never_glue_onto_a_torn_line() {
        let dir = std::env::temp_dir().join(format!("tracer_calib_history_{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let path = dir.join("h.jsonl");
        let _ = fs::remove_file(&path);
        assert_eq!(read(&path).unwrap(), History::default(), "a missing file is an empty history");
        append(&path, &record(1)).unwrap();
        append(&path, &record(2)).unwrap();
        let h = read(&path).unwrap();
        assert_eq!(h.records.iter().map(|r| r.scan_id).collect::<Vec<_>>(), [1, 2]);
        // A crash mid-write: half a line (with a torn multi-byte character).
        let torn = record(3).to_line().replace("/t", "/tÄ");
        let cut = torn.find('Ä').unwrap() + 1;
        fs::OpenOptions::new().append(true).open(&path).unwrap().write_all(&torn.as_bytes()[..cut]).unwrap();
        let h = read(&path).unwrap();
        assert_eq!(h.records.len(), 2);
        assert_eq!(h.skipped.len(), 1, "{:?}", h.skipped);
        assert!(h.skipped[0].contains("h.jsonl:3: skipped a torn last line"), "{:?}", h.skipped);
        append(&path, &record(4)).unwrap();
        let h = read(&path).unwrap();
        assert_eq!(h.records.iter().map(|r| r.scan_id).collect::<Vec<_>>(), [1, 2, 4]);
        assert_eq!(h.skipped.len(), 1);
        assert!(fs::read(&path).unwrap().ends_with(b"}\n"));
        // A file that cannot be read (a directory): an error naming it.
        let e = read(&dir).unwrap_err();
        assert_eq!(e.path, dir.display().to_string());
        assert!(e.to_string().starts_with(&format!("{}: cannot read: ", dir.display())), "{e}");
        // A directory that does not exist: an error, nothing created.
        assert!(append(&dir.join("no/such/h.jsonl"), &record(5)).is_err());
        fs::remove_dir_all(&dir).unwrap();
    }
}
