//! Files the tools read and write: scans as CSV (and, with the bag issue, rosbag2).

pub mod bag;
pub mod csv;
pub mod oma;
pub mod plot;

/// Why a scan file ([`csv::read`], [`oma::read`]) was not read: the file itself could not be
/// read, or what it holds is not what the format says (the parser's words name the file
/// and, where there is one, the line).
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    /// The file could not be read (missing, a directory, no permission, ...).
    #[error("{path}: cannot read: {source}")]
    Unreadable {
        /// The file, as given.
        path: String,
        /// The system's reason.
        #[source]
        source: std::io::Error,
    },
    /// The file was read; its contents are not the format's.
    #[error(transparent)]
    Malformed(#[from] ParseError),
}

/// What a scan file holds is not what its format says ([`csv::parse`], [`oma::parse`]):
/// the parser's words, one line naming the file and, where there is one, the line.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct ParseError(pub String);
