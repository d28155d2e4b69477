//! Persisting the node's parameters into the params file it was started from, without
//! losing anything of anybody else's.
//!
//! A persist writes the parameters whose value differs from what the file gives this node
//! (its own section, the `/**` and pattern sections that match it, and the defaults for
//! what the file does not name), and only those: by [`edit::edit`], in place, in this
//! node's own section. A file that cannot be edited without reformatting it
//! ([`edit::Unsafe`]) is left untouched and the parameters go whole to a sibling file
//! ([`sibling_path`]), which the node reads after the params file at its next start
//! ([`crate::ros`]'s start-up), so nothing is lost; the next persist that can edit the
//! file writes everything there and removes the sibling.
//!
//! The read, edit and write hold an exclusive `flock` on the file's directory, so two
//! nodes of one cell sharing a file do not write over each other's change; the write
//! itself is atomic ([`file::write_atomic`]).

use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use super::edit::{self, Unsafe};
use super::file;
use super::{ParamValue, Parameters};

/// What a persist did.
#[derive(Debug, Clone, PartialEq)]
pub enum Persisted {
    /// The file already gave every value: not written.
    Unchanged,
    /// The file was edited in place.
    Edited,
    /// The file could not be edited safely (why); the parameters went to `path`.
    Sibling { path: PathBuf, why: Unsafe },
}

/// The file a node's parameters go to when `path` cannot be edited safely:
/// `<stem>.persisted.<node name, its namespace's '/' as '.'>.yaml` beside it, e.g.
/// `cells.persisted.cell1.tracer.yaml` for `/cell1/tracer` and `cells.yaml`.
pub fn sibling_path(path: &Path, fqn: &str) -> PathBuf {
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let node = fqn.trim_start_matches('/').replace('/', ".");
    path.with_file_name(format!("{stem}.persisted.{node}.yaml"))
}

/// Of `wanted`, the parameters whose value differs from what the file's `text` gives node
/// `fqn` (a parameter the file does not name: its default; a name that is no parameter of
/// [`Parameters`], such as a QoS override: absent). A file whose values do not apply is an
/// [`Unsafe`] one.
pub fn changes(text: &str, fqn: &str, wanted: &[(String, ParamValue)]) -> Result<Vec<(String, ParamValue)>, Unsafe> {
    let parsed = file::parse(text, "the params file").map_err(|e| Unsafe(format!("it does not read: {e}")))?;
    let mut given = Parameters::default();
    given.apply_file(&parsed, fqn, "the params file").map_err(|e| Unsafe(format!("it does not apply: {e}")))?;
    let in_file = |name: &str| parsed.entries_for(fqn).filter(|e| e.name == name).last().map(|e| e.value.clone());
    Ok(wanted
        .iter()
        .filter(|(name, value)| {
            let now = if Parameters::is_known(name) { given.get(name) } else { in_file(name) };
            match now {
                Some(v) => v != *value,
                None => !value.is_empty_array(),
            }
        })
        .cloned()
        .collect())
}

/// Write `wanted`, node `fqn`'s parameters, into the params file at `path` (module doc).
/// An I/O error leaves the file (and the sibling) as they were.
pub fn persist(path: &Path, fqn: &str, wanted: &[(String, ParamValue)], comment: &str) -> io::Result<Persisted> {
    let _lock = DirLock::new(path)?;
    let text = match fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == io::ErrorKind::NotFound => String::new(),
        Err(e) => return Err(e),
    };
    let sibling = sibling_path(path, fqn);
    let edited = changes(&text, fqn, wanted).and_then(|c| {
        let edited = edit::edit(&text, fqn, &c)?;
        Ok(if text.is_empty() { format!("{}{edited}", file::comment_lines(comment)) } else { edited })
    });
    match edited {
        Ok(new) => {
            // A change always changes the text; the format line alone may too.
            let written = new != text;
            if written {
                file::write_atomic(path, &new)?;
            }
            if sibling.exists() {
                // Everything it held is in the file now.
                fs::remove_file(&sibling)?;
            }
            Ok(if written { Persisted::Edited } else { Persisted::Unchanged })
        }
        Err(why) => {
            file::write_atomic(&sibling, &file::render(fqn, wanted, comment))?;
            Ok(Persisted::Sibling { path: sibling, why })
        }
    }
}

/// An exclusive `flock` on a file's directory while it lives.
struct DirLock {
    /// Held open for the lock; closing it unlocks.
    _dir: fs::File,
}

impl DirLock {
    fn new(path: &Path) -> io::Result<DirLock> {
        use std::os::fd::AsRawFd;
        let dir = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        let f = fs::File::open(dir)?;
        // SAFETY: flock on a descriptor this function owns; no memory is shared.
        if unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_EX) } != 0 {
            return Err(io::Error::last_os_error());
        }
        Ok(DirLock { _dir: f })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("tracer_calib_persist_{name}_{}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn only_what_differs_from_the_file_is_written() {
        let text = "/**:\n  ros__parameters:\n    model: full_tip\n/t:\n  ros__parameters:\n    plate.side: 0.05\n";
        let wanted = vec![
            ("plate.side".to_string(), ParamValue::Double(0.05)),
            ("model".to_string(), ParamValue::String("full_tip".into())),
            ("resample_points".to_string(), ParamValue::Integer(400)),
            ("calibration.covariance".to_string(), ParamValue::DoubleArray(vec![])),
            ("calibration.valid".to_string(), ParamValue::Bool(true)),
            ("qos_overrides./raw_scan.subscription.depth".to_string(), ParamValue::Integer(5)),
        ];
        let c = changes(text, "/t", &wanted).unwrap();
        let names: Vec<&str> = c.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["calibration.valid", "qos_overrides./raw_scan.subscription.depth"]);
    }

    #[test]
    fn a_file_that_cannot_be_edited_goes_to_a_sibling_until_it_can() {
        let d = dir("sibling");
        let path = d.join("cells.yaml");
        // Its own section a flow map: a new key would reflow it.
        let flow = "/**:\n  ros__parameters:\n    use_sim_time: false\n/cell1/tracer: {ros__parameters: {plate.side: 0.045}}  # the PLC's\n";
        fs::write(&path, flow).unwrap();
        let wanted = vec![("calibration.valid".to_string(), ParamValue::Bool(true))];
        let got = persist(&path, "/cell1/tracer", &wanted, "c").unwrap();
        let sibling = d.join("cells.persisted.cell1.tracer.yaml");
        assert_eq!(sibling_path(&path, "/cell1/tracer"), sibling);
        match got {
            Persisted::Sibling { path, why } => {
                assert_eq!(path, sibling);
                assert!(why.0.contains("flow map"), "{why}");
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(fs::read_to_string(&path).unwrap(), flow, "the file is untouched");
        let f = file::read(&sibling).unwrap();
        assert_eq!(f.entries_for("/cell1/tracer").last().unwrap().value, ParamValue::Bool(true));
        // Once the file can be edited, everything goes there and the sibling goes.
        fs::write(&path, "/**:\n  ros__parameters:\n    use_sim_time: false\n").unwrap();
        assert_eq!(persist(&path, "/cell1/tracer", &wanted, "c").unwrap(), Persisted::Edited);
        assert!(!sibling.exists());
        assert_eq!(
            fs::read_to_string(&path).unwrap(),
            "# tracer_calib: params format 2\n/**:\n  ros__parameters:\n    use_sim_time: false\n\n/cell1/tracer:\n  ros__parameters:\n    calibration.valid: true\n"
        );
        assert_eq!(persist(&path, "/cell1/tracer", &wanted, "c").unwrap(), Persisted::Unchanged);
        // A new file starts with the comment and the format line.
        let fresh = d.join("new.yaml");
        persist(&fresh, "/t", &wanted, "written by a test").unwrap();
        assert_eq!(
            fs::read_to_string(&fresh).unwrap(),
            "# written by a test\n# tracer_calib: params format 2\nt:\n  ros__parameters:\n    calibration.valid: true\n"
        );
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn two_writers_of_one_file_keep_both_changes() {
        let d = dir("two");
        let path = d.join("cell.yaml");
        fs::write(&path, "# shared\n").unwrap();
        let threads: Vec<_> = (0..8)
            .map(|i| {
                let path = path.clone();
                std::thread::spawn(move || {
                    let wanted = vec![("resample_points".to_string(), ParamValue::Integer(100 + i))];
                    persist(&path, &format!("/cell{i}/tracer"), &wanted, "").unwrap();
                })
            })
            .collect();
        for t in threads {
            t.join().unwrap();
        }
        let f = file::read(&path).unwrap();
        for i in 0..8 {
            let v = f.entries_for(&format!("/cell{i}/tracer")).last().map(|e| e.value.clone());
            assert_eq!(v, Some(ParamValue::Integer(100 + i)), "cell {i}");
        }
        fs::remove_dir_all(&d).unwrap();
    }
}
