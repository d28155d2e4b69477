//! A params file's YAML as a tree of nodes, each with where it starts: what reading a file
//! ([`super::file`]: lines in errors) and editing it ([`super::edit`]: columns, quoting,
//! flow or block) both need, built once from yaml-rust2's marked events.

use yaml_rust2::parser::{Event, MarkedEventReceiver, Parser};
use yaml_rust2::scanner::{Marker, ScanError, TScalarStyle};

/// Where a node starts: 0-based line, column in characters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Pos {
    pub line: usize,
    pub col: usize,
}

impl Pos {
    /// The 1-based line, as errors name it.
    pub fn line_number(self) -> usize {
        self.line + 1
    }
}

impl From<Marker> for Pos {
    fn from(m: Marker) -> Self {
        Pos { line: m.line().saturating_sub(1), col: m.col() }
    }
}

/// A YAML node with where it starts. (A block collection's start is where the parser
/// marks it, not always its first character; a flow collection starts at its bracket.)
#[derive(Debug, Clone)]
pub enum Y {
    Scalar { text: String, style: TScalarStyle, pos: Pos },
    Seq { items: Vec<Y>, pos: Pos },
    Map { entries: Vec<(Y, Y)>, pos: Pos },
}

impl Y {
    pub fn pos(&self) -> Pos {
        match self {
            Y::Scalar { pos, .. } | Y::Seq { pos, .. } | Y::Map { pos, .. } => *pos,
        }
    }

    /// A scalar in quotes (or a block scalar): never typed as a number or a bool.
    pub fn quoted(&self) -> bool {
        matches!(self, Y::Scalar { style, .. } if !matches!(style, TScalarStyle::Plain))
    }
}

/// The documents of a YAML text, and what in it a reader or an editor may refuse.
#[derive(Debug, Default)]
pub struct Tree {
    pub docs: Vec<Y>,
    /// An alias (`*name`) was seen: its node is left out of the tree.
    pub alias: bool,
    /// An anchor (`&name`) or a tag (`!!float`) was seen.
    pub anchor_or_tag: bool,
}

enum Frame {
    Seq(Vec<Y>, Pos),
    Map(Vec<(Y, Y)>, Option<Y>, Pos),
}

#[derive(Default)]
struct Builder {
    stack: Vec<Frame>,
    tree: Tree,
}

impl Builder {
    fn push(&mut self, node: Y) {
        match self.stack.last_mut() {
            None => self.tree.docs.push(node),
            Some(Frame::Seq(items, _)) => items.push(node),
            // Keys and values alternate: a key waits for its value.
            Some(Frame::Map(entries, pending, _)) => match pending.take() {
                Some(key) => entries.push((key, node)),
                None => *pending = Some(node),
            },
        }
    }
}

impl MarkedEventReceiver for Builder {
    fn on_event(&mut self, ev: Event, mark: Marker) {
        let pos = Pos::from(mark);
        match ev {
            Event::Scalar(text, style, anchor, tag) => {
                self.tree.anchor_or_tag |= anchor != 0 || tag.is_some();
                self.push(Y::Scalar { text, style, pos });
            }
            Event::SequenceStart(anchor, tag) => {
                self.tree.anchor_or_tag |= anchor != 0 || tag.is_some();
                self.stack.push(Frame::Seq(Vec::new(), pos));
            }
            Event::MappingStart(anchor, tag) => {
                self.tree.anchor_or_tag |= anchor != 0 || tag.is_some();
                self.stack.push(Frame::Map(Vec::new(), None, pos));
            }
            Event::SequenceEnd | Event::MappingEnd => match self.stack.pop() {
                Some(Frame::Seq(items, pos)) => self.push(Y::Seq { items, pos }),
                Some(Frame::Map(entries, _, pos)) => self.push(Y::Map { entries, pos }),
                None => {}
            },
            Event::Alias(_) => self.tree.alias = true,
            _ => {}
        }
    }
}

/// The tree of a YAML text, or the parser's error.
pub fn load(text: &str) -> Result<Tree, ScanError> {
    let mut builder = Builder::default();
    Parser::new_from_str(text).load(&mut builder, true)?;
    Ok(builder.tree)
}
