//! Editing a params file in place: this node's keys changed, everything else kept as the
//! integrator wrote it.
//!
//! A cell keeps one params file for several nodes: a `/**` section, the edger's, the
//! tracer's, with the integrator's comments ("certificate 4711", "do not raise"). The node
//! writes back only what is its own:
//!
//! - **its own section** is the one whose key names this node exactly (`/cell1/tracer`, or
//!   `tracer` / `/tracer` at the root); `/**`, `*` patterns and every other node's section
//!   are never touched;
//! - **a key already there** gets its new value in place: only the value's text is
//!   replaced; the key, a comment after it, key order, indentation, quoting of other
//!   values and every other line stay;
//! - **a new key** goes at the end of the section (after the comments indented as its
//!   keys), at the indentation of its keys; **no section** for this node: one is appended at
//!   the end of the file;
//! - **an empty list** removes the key (rcl refuses `[]`: it cannot tell its type);
//! - **the format line** `# tracer_calib: params format 2` goes at the top (an older one is
//!   replaced: an older file is read and upgraded; a newer one is refused on reading,
//!   [`super::file::parse`]).
//!
//! What cannot be done without reformatting the integrator's text is refused with the
//! reason ([`Unsafe`]): an anchor, alias or tag anywhere (a value may be shared with
//! another node), several YAML documents, a key of this node inside a flow map (`{a: 1}`)
//! or a new key into a non-empty one, a multi-line or block scalar, a flow list over
//! several lines. The caller then writes elsewhere and leaves the file as it was.
//!
//! The edited text is parsed again and checked before it is returned: every other
//! section reads exactly as before, and this node reads the values asked for (a later
//! `/**` section setting the same key would override it: refused too).

use std::fmt;

use yaml_rust2::scanner::TScalarStyle;

use super::file::{self, node_matches};
use super::tree::{self, Pos, Y};
use super::value::ParamValue;

/// The params file format this node writes: 1, files without the format line (read and
/// upgraded); 2, files this version edits in place, with the line.
pub const PARAMS_FORMAT: u32 = 2;

/// The start of the format line.
pub const FORMAT_PREFIX: &str = "# tracer_calib: params format ";

/// The format line this node writes.
pub fn format_line() -> String {
    format!("{FORMAT_PREFIX}{PARAMS_FORMAT}")
}

/// The format a params file's text declares (its 0-based line and the number), if any.
pub fn declared_format(text: &str) -> Option<(usize, u32)> {
    text.lines().enumerate().find_map(|(i, line)| {
        let rest = line.trim_start().strip_prefix(FORMAT_PREFIX.trim_end())?.trim_start();
        let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
        Some((i, digits.parse().ok()?))
    })
}

/// Why a file is not edited: what in it the edit would have to reformat.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Unsafe(pub String);

impl fmt::Display for Unsafe {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Unsafe {}

fn unsafe_<T>(why: impl Into<String>) -> Result<T, Unsafe> {
    Err(Unsafe(why.into()))
}

/// The key of a section for node `fqn`: the bare node name at the root namespace
/// (`tracer_calibrator`), else the fully qualified name (`/cell1/tracer`); both are what
/// ROS writes and reads. Quoted if it is not a plain name.
pub fn section_key(fqn: &str) -> String {
    let key = match fqn.strip_prefix('/') {
        Some(bare) if !bare.contains('/') => bare.to_string(),
        _ => fqn.to_string(),
    };
    let plain = key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '/');
    if plain { key } else { super::value::yaml_string(&key) }
}

/// The file's text as lines of characters (a `\r` before a newline kept in its line).
struct Text {
    lines: Vec<Vec<char>>,
}

impl Text {
    fn new(text: &str) -> Text {
        let mut lines: Vec<Vec<char>> = text.split('\n').map(|l| l.chars().collect()).collect();
        if text.ends_with('\n') || text.is_empty() {
            lines.pop();
        }
        Text { lines }
    }

    fn char_at(&self, p: Pos) -> Option<char> {
        self.lines.get(p.line).and_then(|l| l.get(p.col)).copied()
    }

    fn indent(&self, line: usize) -> usize {
        self.lines[line].iter().take_while(|c| **c == ' ').count()
    }

    fn is_blank(&self, line: usize) -> bool {
        self.lines[line].iter().all(|c| c.is_whitespace())
    }

    fn is_comment(&self, line: usize) -> bool {
        self.lines[line].iter().find(|c| !c.is_whitespace()) == Some(&'#')
    }
}

/// Is the node a flow collection (`{...}` or `[...]`)? Block ones start elsewhere.
fn is_flow(text: &Text, node: &Y) -> bool {
    match node {
        Y::Map { pos, .. } => text.char_at(*pos) == Some('{'),
        Y::Seq { pos, .. } => text.char_at(*pos) == Some('['),
        Y::Scalar { .. } => false,
    }
}

/// One replacement: lines `first..first + count` become `with`.
#[derive(Debug)]
struct Splice {
    first: usize,
    count: usize,
    with: Vec<String>,
}

/// The end (exclusive column) of a one-line scalar starting at `pos`, checked against the
/// parser's reading of it; `None` if it does not end on its line as read.
fn scalar_end(text: &Text, pos: Pos, style: TScalarStyle, value: &str) -> Option<usize> {
    let line = text.lines.get(pos.line)?;
    let end = match style {
        TScalarStyle::Plain => {
            let mut end = line.len();
            for i in pos.col..line.len() {
                if line[i] == '#' && i > pos.col && line[i - 1].is_whitespace() {
                    end = i;
                    break;
                }
            }
            while end > pos.col && line[end - 1].is_whitespace() {
                end -= 1;
            }
            let read: String = line[pos.col..end].iter().collect();
            (read == value).then_some(end)?
        }
        TScalarStyle::SingleQuoted | TScalarStyle::DoubleQuoted => quoted_end(line, pos.col)?,
        _ => return None,
    };
    Some(end)
}

/// The column after the closing quote of a quoted scalar whose opening quote (`'` or `"`)
/// is at `open`, if it closes on its line: `''` is a quote inside single quotes, `\`
/// escapes the next character inside double quotes.
fn quoted_end(line: &[char], open: usize) -> Option<usize> {
    let quote = *line.get(open).filter(|q| matches!(q, '\'' | '"'))?;
    let mut i = open + 1;
    loop {
        match *line.get(i)? {
            '\'' if quote == '\'' && line.get(i + 1) == Some(&'\'') => i += 2,
            '\\' if quote == '"' => i += 2,
            c if c == quote => return Some(i + 1),
            _ => i += 1,
        }
    }
}

/// The end (exclusive column) of a flow list starting at `pos` (its `[`), if it closes on
/// the same line.
fn flow_end(text: &Text, pos: Pos) -> Option<usize> {
    let line = text.lines.get(pos.line)?;
    let (mut depth, mut i) = (0usize, pos.col);
    while i < line.len() {
        match line[i] {
            '[' | '{' => depth += 1,
            ']' | '}' => {
                depth -= 1;
                if depth == 0 {
                    return Some(i + 1);
                }
            }
            '\'' | '"' => {
                i = quoted_end(line, i)?;
                continue;
            }
            _ => {}
        }
        i += 1;
    }
    None
}

/// A parameter of this node's section: its dotted name, its key and its value.
struct Leaf<'a> {
    name: String,
    key: &'a Y,
    value: &'a Y,
    /// It sits in a flow map.
    in_flow: bool,
}

fn leaves<'a>(text: &Text, prefix: &str, map: &'a Y, in_flow: bool, out: &mut Vec<Leaf<'a>>) {
    let Y::Map { entries, .. } = map else { return };
    let in_flow = in_flow || is_flow(text, map);
    for (k, v) in entries {
        let Y::Scalar { text: key, .. } = k else { continue };
        let name = if prefix.is_empty() { key.clone() } else { format!("{prefix}.{key}") };
        match v {
            Y::Map { .. } => leaves(text, &name, v, in_flow, out),
            _ => out.push(Leaf { name, key: k, value: v, in_flow }),
        }
    }
}

/// The lines a value takes, from its key's line: (first, last), inclusive.
fn value_lines(text: &Text, leaf: &Leaf) -> Result<(usize, usize), Unsafe> {
    let first = leaf.key.pos().line;
    let last = match leaf.value {
        Y::Scalar { pos, style, text: v } => {
            scalar_end(text, *pos, *style, v)
                .ok_or_else(|| Unsafe(format!("'{}' has a value over several lines", leaf.name)))?;
            pos.line
        }
        Y::Seq { pos, .. } if is_flow(text, leaf.value) => {
            flow_end(text, *pos).ok_or_else(|| Unsafe(format!("'{}' is a flow list over several lines", leaf.name)))?;
            pos.line
        }
        Y::Seq { items, .. } => items.last().map(|i| i.pos().line).unwrap_or(first),
        Y::Map { .. } => unreachable!("a leaf is no map"),
    };
    Ok((first, last))
}

/// The splice that gives `leaf` the value `value` (`None`: remove it).
fn replace(text: &Text, leaf: &Leaf, value: Option<&ParamValue>) -> Result<Splice, Unsafe> {
    if leaf.in_flow {
        return unsafe_(format!("'{}' is in a flow map ({{...}}): changing it would reflow it", leaf.name));
    }
    let (first, last) = value_lines(text, leaf)?;
    let Some(value) = value else {
        // Removed with its lines: the key's line must hold nothing else of the file's.
        if text.indent(first) != leaf.key.pos().col {
            return unsafe_(format!("'{}' shares its line with another key", leaf.name));
        }
        return Ok(Splice { first, count: last - first + 1, with: Vec::new() });
    };
    let on_line = |pos: Pos, end: usize, new: &str| {
        let line = &text.lines[pos.line];
        let mut s: String = line[..pos.col].iter().collect();
        s.push_str(new);
        s.extend(&line[end..]);
        Splice { first: pos.line, count: 1, with: vec![s] }
    };
    match leaf.value {
        Y::Scalar { pos, style, text: v } => {
            let end = scalar_end(text, *pos, *style, v).expect("checked by value_lines");
            Ok(on_line(*pos, end, &value.to_yaml()))
        }
        Y::Seq { pos, .. } if is_flow(text, leaf.value) => {
            let end = flow_end(text, *pos).expect("checked by value_lines");
            Ok(on_line(*pos, end, &value.to_yaml()))
        }
        Y::Seq { items, .. } => {
            // A block list (`ros2 param dump` writes them): one `- item` a line, kept so.
            let Some(first_item) = items.first() else {
                return unsafe_(format!("'{}' is an empty block list", leaf.name));
            };
            let start = first_item.pos().line;
            let dash = text.indent(start);
            for (n, item) in items.iter().enumerate() {
                let Y::Scalar { pos, style, text: v } = item else {
                    return unsafe_(format!("'{}' is a list of lists or maps", leaf.name));
                };
                let end = scalar_end(text, *pos, *style, v);
                let line = &text.lines[pos.line];
                let shape = pos.line == start + n
                    && text.indent(pos.line) == dash
                    && line.get(dash) == Some(&'-')
                    && end.is_some_and(|e| line[e..].iter().all(|c| c.is_whitespace()));
                if !shape {
                    return unsafe_(format!(
                        "'{}' is a block list with comments or several items a line: rewriting it would lose them",
                        leaf.name
                    ));
                }
            }
            if start == first {
                return unsafe_(format!("'{}' shares its line with its list", leaf.name));
            }
            let with = block_items(value).into_iter().map(|item| format!("{}- {item}", " ".repeat(dash))).collect();
            Ok(Splice { first: start, count: last - start + 1, with })
        }
        Y::Map { .. } => unreachable!("a leaf is no map"),
    }
}

/// The items of an array value as YAML scalars.
fn block_items(value: &ParamValue) -> Vec<String> {
    match value {
        ParamValue::BoolArray(v) => v.iter().map(|b| ParamValue::Bool(*b).to_yaml()).collect(),
        ParamValue::IntegerArray(v) => v.iter().map(|i| ParamValue::Integer(*i).to_yaml()).collect(),
        ParamValue::DoubleArray(v) => v.iter().map(|d| ParamValue::Double(*d).to_yaml()).collect(),
        ParamValue::StringArray(v) => v.iter().map(|s| ParamValue::String(s.clone()).to_yaml()).collect(),
        other => vec![other.to_yaml()],
    }
}

/// The indentation of a section's `ros__parameters:` and of its keys, from the file's
/// first block section (2 and 4 if it has none).
fn indents(text: &Text, top: Option<&Y>) -> (usize, usize) {
    let first = top.and_then(|t| match t {
        Y::Map { entries, .. } => entries.iter().find_map(|(_, body)| match body {
            Y::Map { entries, .. } if !is_flow(text, body) => entries.first().and_then(|(k, params)| match params {
                Y::Map { entries, .. } if !is_flow(text, params) => {
                    entries.first().map(|(pk, _)| (k.pos().col, pk.pos().col))
                }
                _ => None,
            }),
            _ => None,
        }),
        _ => None,
    });
    match first {
        Some((a, b)) if a > 0 && b > a => (a, b),
        _ => (2, 4),
    }
}

/// `text` with this node's (`fqn`) parameters in `changes` set: each to its value, an
/// empty list removed. Everything else stays as it is (module doc); [`Unsafe`] if that
/// cannot be done.
pub fn edit(text: &str, fqn: &str, changes: &[(String, ParamValue)]) -> Result<String, Unsafe> {
    let before = file::parse(text, "the params file").map_err(|e| Unsafe(format!("it does not read: {e}")))?;
    let t = Text::new(text);
    let yaml = tree::load(text).map_err(|e| Unsafe(format!("it is not valid YAML: {}", e.info())))?;
    if yaml.alias || yaml.anchor_or_tag {
        return unsafe_("it has a YAML anchor, alias or tag: a value may be shared with another node's");
    }
    if yaml.docs.len() > 1 {
        return unsafe_("it holds several YAML documents");
    }
    let top = yaml.docs.first();
    if let Some(top) = top
        && is_flow(&t, top)
    {
        return unsafe_("its node sections are a flow map ({...}): adding to it would reflow it");
    }
    let sections: &[(Y, Y)] = match top {
        Some(Y::Map { entries, .. }) => entries,
        _ => &[],
    };
    // This node's own section: the last one naming it exactly.
    let own = sections.iter().enumerate().rev().find(|(_, (k, _))| match k {
        Y::Scalar { text, .. } => !text.contains('*') && node_matches(text, fqn),
        _ => false,
    });
    let mut splices = Vec::new();
    let mut new_keys: Vec<String> = Vec::new();
    let params = own.and_then(|(_, (_, body))| match body {
        Y::Map { entries, .. } => {
            entries.iter().find(|(k, _)| matches!(k, Y::Scalar { text, .. } if text == "ros__parameters"))
        }
        _ => None,
    });
    if own.is_some() && params.is_none() {
        return unsafe_("this node's section has no ros__parameters map");
    }
    let mut found = Vec::new();
    if let Some((_, params)) = params {
        leaves(&t, "", params, false, &mut found);
    }
    for (name, value) in changes {
        let leaf = found.iter().rev().find(|l| &l.name == name);
        let remove = value.is_empty_array();
        match leaf {
            Some(leaf) => splices.push(replace(&t, leaf, (!remove).then_some(value))?),
            None if remove => {}
            None => new_keys.push(format!("{name}: {}", value.to_yaml())),
        }
    }
    if !new_keys.is_empty() {
        match (own, params) {
            (Some((i, _)), Some((pk, pv))) => {
                let Y::Map { entries, pos } = pv else {
                    return unsafe_("this node's ros__parameters is not a map");
                };
                let indent = if is_flow(&t, pv) {
                    // `ros__parameters: {}` (what a node with no parameter writes): the
                    // braces go, the keys follow as a block.
                    if !entries.is_empty() {
                        return unsafe_(
                            "this node's ros__parameters is a flow map ({...}): adding to it would reflow it",
                        );
                    }
                    let end =
                        flow_end(&t, *pos).ok_or_else(|| Unsafe("ros__parameters: { over several lines".into()))?;
                    let line = &t.lines[pos.line];
                    let rest: String = line[end..].iter().collect();
                    let mut s: String = line[..pos.col].iter().collect::<String>().trim_end().to_string();
                    if !rest.trim().is_empty() {
                        s.push(' ');
                        s.push_str(rest.trim_start());
                    }
                    splices.push(Splice { first: pos.line, count: 1, with: vec![s] });
                    let (a, b) = indents(&t, top);
                    pk.pos().col + (b - a)
                } else {
                    entries.first().map(|(k, _)| k.pos().col).unwrap_or(pk.pos().col + 2)
                };
                // After the section's last line of its own: its keys, values and the
                // comments indented as its keys; before the next section and its comments.
                let next = sections.get(i + 1).map(|(k, _)| k.pos().line).unwrap_or(t.lines.len());
                let mut after = next;
                while after > pk.pos().line + 1 {
                    let l = after - 1;
                    if t.is_blank(l) || (t.is_comment(l) && t.indent(l) < indent) {
                        after = l;
                    } else {
                        break;
                    }
                }
                let with = new_keys.iter().map(|k| format!("{}{k}", " ".repeat(indent))).collect();
                splices.push(Splice { first: after, count: 0, with });
            }
            _ => {
                let (a, b) = indents(&t, top);
                let mut with = Vec::new();
                if t.lines.last().is_some_and(|l| !l.iter().all(|c| c.is_whitespace())) {
                    with.push(String::new());
                }
                with.push(format!("{}:", section_key(fqn)));
                with.push(format!("{}ros__parameters:", " ".repeat(a)));
                with.extend(new_keys.iter().map(|k| format!("{}{k}", " ".repeat(b))));
                splices.push(Splice { first: t.lines.len(), count: 0, with });
            }
        }
    }
    // The format line: replaced where an older one stands, else put first.
    match declared_format(text) {
        Some((_, n)) if n == PARAMS_FORMAT => {}
        Some((line, _)) => splices.push(Splice { first: line, count: 1, with: vec![format_line()] }),
        None => splices.push(Splice { first: 0, count: 0, with: vec![format_line()] }),
    }
    let out = apply(&t, splices);
    check(&before, &out, fqn, changes)?;
    Ok(out)
}

/// The lines of `t` with the splices made (they do not overlap; later ones first).
fn apply(t: &Text, mut splices: Vec<Splice>) -> String {
    let mut lines: Vec<String> = t.lines.iter().map(|l| l.iter().collect()).collect();
    // Stable: of two insertions at one line, the one asked first stays first.
    splices.sort_by_key(|s| std::cmp::Reverse((s.first, s.count)));
    for s in splices {
        lines.splice(s.first..s.first + s.count, s.with);
    }
    let mut out = lines.join("\n");
    out.push('\n');
    out
}

/// The edit did what it says: every other section reads as before, this node's own reads
/// the values asked for, and nothing else of it changed.
fn check(before: &file::ParamsFile, out: &str, fqn: &str, changes: &[(String, ParamValue)]) -> Result<(), Unsafe> {
    let after =
        file::parse(out, "the edited file").map_err(|e| Unsafe(format!("the edit would not read back: {e}")))?;
    let exact = |s: &file::Section| !s.node.contains('*') && node_matches(&s.node, fqn);
    let others = |f: &file::ParamsFile| -> Vec<(String, Vec<(String, ParamValue)>)> {
        f.sections
            .iter()
            .filter(|s| !exact(s))
            .map(|s| (s.node.clone(), s.params.iter().map(|e| (e.name.clone(), e.value.clone())).collect()))
            .collect()
    };
    if others(before) != others(&after) {
        return unsafe_("the edit would change another node's section");
    }
    let resolved = |f: &file::ParamsFile, name: &str| {
        f.entries_for(fqn).filter(|e| e.name == name).last().map(|e| e.value.clone())
    };
    for (name, value) in changes {
        let got = resolved(&after, name);
        let ok =
            if value.is_empty_array() { got.is_none_or(|g| g.is_empty_array()) } else { got.as_ref() == Some(value) };
        if !ok {
            let by = after
                .sections
                .iter()
                .rev()
                .find(|s| node_matches(&s.node, fqn) && s.params.iter().any(|e| &e.name == name));
            return unsafe_(match by {
                Some(s) if !exact(s) => {
                    format!("section '{}' sets '{name}' for this node after its own section", s.node)
                }
                _ => format!("'{name}' would not read back as written"),
            });
        }
    }
    let names: Vec<&str> = before.entries_for(fqn).map(|e| e.name.as_str()).collect();
    for name in names {
        if !changes.iter().any(|(n, _)| n == name) && resolved(before, name) != resolved(&after, name) {
            return unsafe_(format!("the edit would change '{name}'"));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
