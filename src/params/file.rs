//! ROS 2 parameter files: read them the way `--params-file` does, write them so that
//! stock ROS 2 nodes (and this node) read them back.
//!
//! ```yaml
//! /cell1/tracer:                 # node name, fully qualified; `/**` and `*` match
//!   ros__parameters:
//!     calibration.alpha0: 0.0349 # dotted names, or nested maps that flatten to them
//!     plate:
//!       side: 0.045
//! ```
//!
//! Reading keeps the line of every key, so a bad value is reported as
//! `FILE:LINE: KEY: what is wrong`. Writing goes through a temporary file in the same
//! directory, `fsync`, and `rename` over the old file, then an `fsync` of the
//! directory: a crash leaves the old file or the new one, never half of either.

use std::fmt;
use std::fs;
use std::io::Write;
use std::path::Path;

use super::tree::{self, Y};

use super::value::ParamValue;

/// One parameter as the file gives it.
#[derive(Debug, Clone, PartialEq)]
pub struct Entry {
    /// Dotted name, e.g. `calibration.alpha0`.
    pub name: String,
    pub value: ParamValue,
    /// 1-based line of the key.
    pub line: usize,
}

/// The parameters of one node-name key.
#[derive(Debug, Clone, PartialEq)]
pub struct Section {
    /// The node name as written (`/cell1/tracer`, `tracer_calibrator`, `/**`).
    pub node: String,
    pub line: usize,
    pub params: Vec<Entry>,
}

/// A parsed parameter file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ParamsFile {
    pub sections: Vec<Section>,
}

/// What is wrong with a parameter file, and where.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamsFileError {
    pub path: String,
    pub line: Option<usize>,
    pub key: Option<String>,
    pub message: String,
}

impl fmt::Display for ParamsFileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path)?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if let Some(key) = &self.key {
            write!(f, ": {key}")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for ParamsFileError {}

impl ParamsFileError {
    pub fn new(path: &str, line: Option<usize>, key: Option<&str>, message: impl Into<String>) -> Self {
        ParamsFileError { path: path.to_string(), line, key: key.map(str::to_string), message: message.into() }
    }
}

/// Parse the text of a parameter file; `path` only names it in errors. A file whose
/// format line ([`super::edit::declared_format`]) names a newer format than this node's
/// is refused.
pub fn parse(text: &str, path: &str) -> Result<ParamsFile, ParamsFileError> {
    if let Some((line, n)) = super::edit::declared_format(text)
        && n > super::edit::PARAMS_FORMAT
    {
        return Err(ParamsFileError::new(
            path,
            Some(line + 1),
            None,
            format!(
                "params format {n}, written by a newer tracer_calib: this one reads formats up to {} (run the newer version, or give this one a file of its own)",
                super::edit::PARAMS_FORMAT
            ),
        ));
    }
    let tree = tree::load(text).map_err(|e| {
        ParamsFileError::new(path, Some(e.marker().line()), None, format!("not valid YAML: {}", e.info()))
    })?;
    if tree.alias {
        return Err(ParamsFileError::new(path, None, None, "YAML aliases are not supported in parameter files"));
    }
    let mut file = ParamsFile::default();
    for doc in tree.docs {
        let Y::Map { entries, .. } = doc else {
            return Err(ParamsFileError::new(
                path,
                Some(doc.pos().line_number()),
                None,
                "expected a map of node names to their ros__parameters",
            ));
        };
        for (key, body) in entries {
            let node = scalar_key(&key, path)?;
            let Y::Map { entries: inner, .. } = &body else {
                return Err(ParamsFileError::new(
                    path,
                    Some(key.pos().line_number()),
                    Some(&node),
                    "expected 'ros__parameters:' under the node name",
                ));
            };
            let mut params = Vec::new();
            for (k, v) in inner {
                let name = scalar_key(k, path)?;
                if name != "ros__parameters" {
                    return Err(ParamsFileError::new(
                        path,
                        Some(k.pos().line_number()),
                        Some(&name),
                        format!("expected 'ros__parameters' under node '{node}'"),
                    ));
                }
                flatten("", v, path, &mut params)?;
            }
            file.sections.push(Section { node, line: key.pos().line_number(), params });
        }
    }
    Ok(file)
}

/// Read and parse a parameter file.
pub fn read(path: &Path) -> Result<ParamsFile, ParamsFileError> {
    let shown = path.display().to_string();
    let text =
        fs::read_to_string(path).map_err(|e| ParamsFileError::new(&shown, None, None, format!("cannot read: {e}")))?;
    parse(&text, &shown)
}

fn scalar_key(node: &Y, path: &str) -> Result<String, ParamsFileError> {
    match node {
        Y::Scalar { text, .. } => Ok(text.clone()),
        other => Err(ParamsFileError::new(path, Some(other.pos().line_number()), None, "a key must be a plain name")),
    }
}

/// Nested maps under `ros__parameters` flatten to dotted names, as ROS does.
fn flatten(prefix: &str, node: &Y, path: &str, out: &mut Vec<Entry>) -> Result<(), ParamsFileError> {
    let Y::Map { entries, pos } = node else {
        return Err(ParamsFileError::new(
            path,
            Some(node.pos().line_number()),
            Some(prefix),
            "expected a map of parameter names to values",
        ));
    };
    if entries.is_empty() && !prefix.is_empty() {
        return Err(ParamsFileError::new(path, Some(pos.line_number()), Some(prefix), "empty map: no value given"));
    }
    for (k, v) in entries {
        let key = scalar_key(k, path)?;
        let name = if prefix.is_empty() { key } else { format!("{prefix}.{key}") };
        let line = k.pos().line_number();
        match v {
            Y::Map { .. } => flatten(&name, v, path, out)?,
            Y::Scalar { text, .. } => {
                if text.is_empty() && !v.quoted() {
                    return Err(ParamsFileError::new(path, Some(line), Some(&name), "no value given"));
                }
                out.push(Entry { name, value: ParamValue::from_yaml_scalar(text, v.quoted()), line })
            }
            Y::Seq { items, .. } => {
                let value = array(items).ok_or_else(|| {
                    ParamsFileError::new(path, Some(line), Some(&name), "an array must hold scalars of one type")
                })?;
                out.push(Entry { name, value, line });
            }
        }
    }
    Ok(())
}

fn array(items: &[Y]) -> Option<ParamValue> {
    let values: Vec<ParamValue> = items
        .iter()
        .map(|n| match n {
            Y::Scalar { text, .. } => Some(ParamValue::from_yaml_scalar(text, n.quoted())),
            _ => None,
        })
        .collect::<Option<_>>()?;
    // In a file, integers among doubles are doubles.
    let numbers: Option<Vec<f64>> = values.iter().map(ParamValue::as_f64).collect();
    ParamValue::array_of(values).or_else(|| numbers.map(ParamValue::DoubleArray))
}

impl ParamsFile {
    /// The entries that apply to the node with fully qualified name `fqn`
    /// (e.g. `/cell1/tracer`), in file order: later entries override earlier ones.
    pub fn entries_for<'a>(&'a self, fqn: &'a str) -> impl Iterator<Item = &'a Entry> + 'a {
        self.sections.iter().filter(move |s| node_matches(&s.node, fqn)).flat_map(|s| s.params.iter())
    }
}

/// Does a node-name key of a parameter file match `fqn`? A key without a leading `/`
/// is taken from the root; `*` matches one name token, `**` any number of tokens.
pub fn node_matches(key: &str, fqn: &str) -> bool {
    let key = key.trim_start_matches('/');
    let fqn = fqn.trim_start_matches('/');
    let k: Vec<&str> = if key.is_empty() { Vec::new() } else { key.split('/').collect() };
    let n: Vec<&str> = if fqn.is_empty() { Vec::new() } else { fqn.split('/').collect() };
    fn go(k: &[&str], n: &[&str]) -> bool {
        match (k.first(), n.first()) {
            (None, None) => true,
            (Some(&"**"), _) => go(&k[1..], n) || (!n.is_empty() && go(k, &n[1..])),
            (Some(&"*"), Some(_)) => go(&k[1..], &n[1..]),
            (Some(a), Some(b)) => a == b && go(&k[1..], &n[1..]),
            _ => false,
        }
    }
    go(&k, &n)
}

/// The text of a parameter file holding `params` for node `fqn`.
///
/// At the root namespace the key is the bare node name (`tracer_calibrator:`), else
/// the fully qualified name (`/cell1/tracer:`); both are what ROS writes and reads.
pub fn render(fqn: &str, params: &[(String, ParamValue)], comment: &str) -> String {
    let key = super::edit::section_key(fqn);
    let mut out = comment_lines(comment);
    out.push_str(&super::edit::format_line());
    out.push('\n');
    if params.is_empty() {
        // A bare `ros__parameters:` would be null, not a map: no reader takes it.
        out.push_str(&format!("{key}:\n  ros__parameters: {{}}\n"));
        return out;
    }
    out.push_str(&format!("{key}:\n  ros__parameters:\n"));
    for (name, value) in params {
        // An empty list is left out: rcl's parser refuses an empty sequence (it cannot
        // tell its type), and a parameter the file does not name keeps its default.
        if value.is_empty_array() {
            continue;
        }
        out.push_str(&format!("    {name}: {}\n", value.to_yaml()));
    }
    out
}

/// `comment` as YAML comment lines (`# ` before each), for the top of a file.
pub fn comment_lines(comment: &str) -> String {
    comment.lines().map(|l| format!("# {l}\n")).collect()
}

/// Remove the temporary files a writer killed mid-write left beside `path`
/// (`.NAME.tmp.PID` whose process is gone); returns how many. A live writer's file is
/// left alone.
pub fn remove_stale_temp_files(path: &Path) -> usize {
    let (Some(dir), Some(name)) = (path.parent(), path.file_name()) else { return 0 };
    let dir = if dir.as_os_str().is_empty() { Path::new(".") } else { dir };
    let prefix = format!(".{}.tmp.", name.to_string_lossy());
    let Ok(entries) = fs::read_dir(dir) else { return 0 };
    let mut removed = 0;
    for entry in entries.flatten() {
        let file = entry.file_name();
        let Some(pid) = file.to_str().and_then(|f| f.strip_prefix(&prefix)) else { continue };
        let Ok(pid) = pid.parse::<u32>() else { continue };
        let alive = pid == std::process::id() || Path::new(&format!("/proc/{pid}")).exists();
        if !alive && fs::remove_file(entry.path()).is_ok() {
            removed += 1;
        }
    }
    removed
}

/// Replace `path` with `contents` atomically: a temporary file beside it, written and
/// `fsync`ed, renamed over `path`, and the directory `fsync`ed.
pub fn write_atomic(path: &Path, contents: &str) -> std::io::Result<()> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    let name = path.file_name().ok_or_else(|| std::io::Error::other("the path names no file"))?;
    let tmp = dir.join(format!(".{}.tmp.{}", name.to_string_lossy(), std::process::id()));
    let result = (|| {
        let mut f = fs::OpenOptions::new().write(true).create(true).truncate(true).open(&tmp)?;
        f.write_all(contents.as_bytes())?;
        f.sync_all()?;
        drop(f);
        fs::rename(&tmp, path)?;
        fs::File::open(&dir)?.sync_all()
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    const FILE: &str = "\
/cell1/tracer:
  ros__parameters:
    calibration.alpha0: 0.0349
    calibration:
      valid: true
    plate:
      side: 0.045
    model: full
    resample_points: 400
    tags: [a, b]
/**:
  ros__parameters:
    use_sim_time: false
";

    #[test]
    fn sections_flatten_and_keep_lines() {
        let f = parse(FILE, "x.yaml").unwrap();
        assert_eq!(f.sections.len(), 2);
        let e: Vec<_> = f.entries_for("/cell1/tracer").collect();
        let names: Vec<_> = e.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "calibration.alpha0",
                "calibration.valid",
                "plate.side",
                "model",
                "resample_points",
                "tags",
                "use_sim_time"
            ]
        );
        assert_eq!(e[0].value, ParamValue::Double(0.0349));
        assert_eq!(e[0].line, 3);
        assert_eq!(e[2].line, 7);
        assert_eq!(e[4].value, ParamValue::Integer(400));
        assert_eq!(e[5].value, ParamValue::StringArray(vec!["a".into(), "b".into()]));
        assert_eq!(f.entries_for("/cell2/tracer").count(), 1);
    }

    #[test]
    fn node_name_patterns() {
        assert!(node_matches("/**", "/a/b"));
        assert!(node_matches("tracer_calibrator", "/tracer_calibrator"));
        assert!(node_matches("/**/tracer", "/cell1/tracer"));
        assert!(node_matches("/*/tracer", "/cell1/tracer"));
        assert!(!node_matches("/*/tracer", "/tracer"));
        assert!(!node_matches("/cell1/tracer", "/cell2/tracer"));
    }

    #[test]
    fn errors_name_file_line_and_key() {
        let e = parse("n:\n  ros__parameters:\n    a: [1, x]\n", "p.yaml").unwrap_err();
        assert_eq!(e.to_string(), "p.yaml:3: a: an array must hold scalars of one type");
        let e = parse("n:\n  params:\n    a: 1\n", "p.yaml").unwrap_err();
        assert_eq!(e.to_string(), "p.yaml:2: params: expected 'ros__parameters' under node 'n'");
        let e = parse("n:\n  ros__parameters:\n    a: [1\n", "p.yaml").unwrap_err();
        assert!(e.to_string().starts_with("p.yaml:"), "{e}");
        assert!(e.to_string().contains("not valid YAML"), "{e}");
        let e = parse("- 1\n", "p.yaml").unwrap_err();
        assert_eq!(e.line, Some(1));
        let e = parse("n:\n  ros__parameters:\n    a:\n", "p.yaml").unwrap_err();
        assert_eq!(e.to_string(), "p.yaml:3: a: no value given");
    }

    #[test]
    fn render_reads_back_and_writes_atomically() {
        let params = vec![
            ("calibration.alpha0".to_string(), ParamValue::Double(0.0349)),
            ("encoder.meters_per_count".to_string(), ParamValue::Double(1e-6)),
            ("calibration.valid".to_string(), ParamValue::Bool(true)),
            ("model".to_string(), ParamValue::String("full".into())),
            ("resample_points".to_string(), ParamValue::Integer(400)),
        ];
        for fqn in ["/tracer_calibrator", "/cell1/tracer"] {
            let text = render(fqn, &params, "written by a test");
            assert!(text.starts_with("# written by a test\n"));
            let f = parse(&text, "t").unwrap();
            let back: Vec<_> = f.entries_for(fqn).map(|e| (e.name.clone(), e.value.clone())).collect();
            assert_eq!(back, params);
        }
        // An empty list is left out (rcl refuses `[]`); a full one reads back.
        let covariance = ("calibration.covariance".to_string(), ParamValue::DoubleArray(vec![1e-12, -2.5e-13]));
        let empty = ("other.list".to_string(), ParamValue::DoubleArray(Vec::new()));
        let text = render("/t", &[covariance.clone(), empty], "");
        assert!(!text.contains("other.list"), "{text}");
        let back: Vec<_> =
            parse(&text, "t").unwrap().entries_for("/t").map(|e| (e.name.clone(), e.value.clone())).collect();
        assert_eq!(back, [covariance]);
        let dir = std::env::temp_dir().join(format!("tracer_calib_params_{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let path = dir.join("p.yaml");
        write_atomic(&path, "old\n").unwrap();
        write_atomic(&path, "new\n").unwrap();
        assert_eq!(fs::read_to_string(&path).unwrap(), "new\n");
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 1, "no temporary file left behind");
        // A temporary file of a dead writer is cleaned up, a live one's is not.
        let stale = dir.join(".p.yaml.tmp.4000000000");
        let live = dir.join(format!(".p.yaml.tmp.{}", std::process::id()));
        fs::write(&stale, "half").unwrap();
        fs::write(&live, "busy").unwrap();
        assert_eq!(remove_stale_temp_files(&path), 1);
        assert!(!stale.exists() && live.exists());
        fs::remove_dir_all(&dir).unwrap();
    }
}
