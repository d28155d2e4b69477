//! Plain CDR (XCDR version 1), as ROS 2 puts messages on the DDS wire and in rosbag2 files.
//!
//! - a 4-byte *encapsulation header* precedes the payload: `00 01 00 00` for little-endian CDR
//!   (`00 00 00 00` for big-endian). Byte 1 selects the byte order; bytes 2-3 are options
//!   (DDS writers put the count of trailing padding bytes there). DDS adds and strips the
//!   header itself; rosbag2 stores it with each message. [`to_cdr`] and [`from_cdr`] handle it
//!   for files and tests;
//! - every primitive is aligned to its own size (1, 2, 4 or 8 bytes), counted from the first
//!   byte *after* the encapsulation header; padding bytes are zero;
//! - `bool`, `byte`, `uint8`, `char` are one octet; `float64` is 8 bytes, aligned to 8;
//! - `string` is a `u32` length that *includes* the terminating NUL, then the bytes, then NUL;
//! - an unbounded or bounded sequence `T[]` / `T[<=N]` is a `u32` element count, then the
//!   elements (each aligned as usual); a fixed array `T[N]` has no count;
//! - nested messages are inlined, with no alignment of their own beyond their first member;
//! - constants (`uint8 TARGET_LENS=3`) are not on the wire; here they are associated consts.
//!
//! The (de)serializer is rustdds', the one the DDS publishers and subscriptions use.

use rustdds::RepresentationIdentifier;
use serde::{Serialize, de::DeserializeOwned};

/// Encapsulation header of little-endian plain CDR: `00 01`, options `00 00`.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Why CDR bytes could not be decoded or encoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CdrError {
    /// Fewer than the 4 bytes of the encapsulation header.
    #[error("CDR data too short for the 4-byte encapsulation header ({0} bytes)")]
    TooShort(usize),
    /// An encapsulation other than plain CDR (e.g. XCDR2 or parameter lists).
    #[error("unsupported CDR encapsulation {} (only plain CDR: 00 00 or 00 01)", hex_pair(.0))]
    Encapsulation([u8; 2]),
    /// The CDR (de)serializer failed: truncated data, a bad bool, bad UTF-8...
    #[error("CDR: {0}")]
    Codec(String),
    /// More bytes followed the message than the at most 3 bytes of padding: probably the
    /// wrong type.
    #[error("{0} unexpected bytes after the message (wrong message type?)")]
    TrailingBytes(usize),
}

fn hex_pair(bytes: &[u8; 2]) -> String {
    format!("{:02x} {:02x}", bytes[0], bytes[1])
}

/// Serializes `value` as little-endian plain CDR, with the encapsulation header, as ROS 2 puts it
/// on the wire and in rosbag2 files.
pub fn to_cdr<T: Serialize>(value: &T) -> Result<Vec<u8>, CdrError> {
    let mut out = CDR_LE_HEADER.to_vec();
    rustdds::serialization::to_writer_with_rep_id(&mut out, value, RepresentationIdentifier::CDR_LE)
        .map_err(|e| CdrError::Codec(e.to_string()))?;
    Ok(out)
}

/// Deserializes plain CDR with its encapsulation header (either byte order).
///
/// Up to 3 trailing bytes are accepted (DDS and rosbag2 pad payloads to a multiple of 4);
/// more is an error, since it usually means the bytes are of another type.
pub fn from_cdr<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, CdrError> {
    let (payload, rep_id) = split_header(bytes)?;
    let (value, used) = rustdds::serialization::deserialize_from_cdr_with_rep_id::<T>(payload, rep_id)
        .map_err(|e| CdrError::Codec(e.to_string()))?;
    let rest = payload.len().saturating_sub(used);
    if rest > 3 {
        return Err(CdrError::TrailingBytes(rest));
    }
    Ok(value)
}

/// [`from_cdr`] for a message type, which also reads what an earlier version of its
/// definition wrote (a bag recorded before fields were appended to it):
/// [`super::RosMsg::from_earlier_cdr`]. The error is the current layout's.
pub fn from_cdr_msg<T: super::RosMsg>(bytes: &[u8]) -> Result<T, CdrError> {
    from_cdr(bytes).or_else(|e| {
        let (payload, rep_id) = split_header(bytes)?;
        T::from_earlier_cdr(payload, rep_id).ok_or(e)
    })
}

/// The payload and byte order of CDR bytes with their encapsulation header.
fn split_header(bytes: &[u8]) -> Result<(&[u8], RepresentationIdentifier), CdrError> {
    if bytes.len() < 4 {
        return Err(CdrError::TooShort(bytes.len()));
    }
    let rep_id = match [bytes[0], bytes[1]] {
        [0x00, 0x00] => RepresentationIdentifier::CDR_BE,
        [0x00, 0x01] => RepresentationIdentifier::CDR_LE,
        other => return Err(CdrError::Encapsulation(other)),
    };
    Ok((&bytes[4..], rep_id))
}

/// `T` decoded from a CDR payload that it fills (up to 3 bytes of padding after it), or
/// `None`: for the earlier layouts of a message ([`super::RosMsg::from_earlier_cdr`]).
pub fn decode_whole<T: DeserializeOwned>(payload: &[u8], rep_id: RepresentationIdentifier) -> Option<T> {
    let (value, used) = rustdds::serialization::deserialize_from_cdr_with_rep_id::<T>(payload, rep_id).ok()?;
    (payload.len().saturating_sub(used) <= 3).then_some(value)
}

/// A sequence appended last to a message that subscribers must read from publishers built
/// before it was (a tracer's driver against an earlier `RawScan`): serde's
/// `deserialize_with` for such a field. A payload that ends where the field would begin
/// fails before the sequence's count is read, before the visitor is entered: the field is
/// absent, and reads as empty. A payload that has the count but ends within its elements
/// is truncated, and stays an error.
pub fn absent_at_end<'de, D, T>(deserializer: D) -> Result<Vec<T>, D::Error>
where
    D: serde::Deserializer<'de>,
    T: serde::Deserialize<'de>,
{
    use std::cell::Cell;
    struct Elements<'a, T>(&'a Cell<bool>, std::marker::PhantomData<T>);
    impl<'de, T: serde::Deserialize<'de>> serde::de::Visitor<'de> for Elements<'_, T> {
        type Value = Vec<T>;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("a sequence")
        }
        fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<Vec<T>, A::Error> {
            self.0.set(true);
            let mut out = Vec::with_capacity(seq.size_hint().unwrap_or(0).min(1 << 16));
            while let Some(x) = seq.next_element()? {
                out.push(x);
            }
            Ok(out)
        }
    }
    let entered = Cell::new(false);
    match deserializer.deserialize_seq(Elements(&entered, std::marker::PhantomData)) {
        Ok(v) => Ok(v),
        Err(_) if !entered.get() => Ok(Vec::new()),
        Err(e) => Err(e),
    }
}
