use core::ops::Bound::{Included, Unbounded};
use std::{
  cmp::{max, min}, // tracer_calib patch: min
  collections::BTreeMap,
};

#[allow(unused_imports)]
use log::{debug, error, info, trace, warn};

use crate::{
  discovery::sedp_messages::DiscoveredWriterData,
  messages::vendor_id::VendorId, // tracer_calib patch
  rtps::constant::{MAX_TRACKED_CHANGES_PER_WRITER, REPAIR_REQUEST_BYTES}, // tracer_calib patch
  structure::{
    guid::{EntityId, GUID},
    locator::Locator,
    sequence_number::SequenceNumber,
    time::Timestamp,
  },
};

#[derive(Debug)] // these are not cloneable, because contained data may be large
pub(crate) struct RtpsWriterProxy {
  /// Identifies the remote matched Writer
  pub remote_writer_guid: GUID,

  /// List of unicast (address, port) combinations that can be used to send
  /// messages to the matched Writer or Writers. The list may be empty.
  pub unicast_locator_list: Vec<Locator>,

  /// List of multicast (address, port) combinations that can be used to send
  /// messages to the matched Writer or Writers. The list may be empty.
  pub multicast_locator_list: Vec<Locator>,

  /// Identifies the group to which the matched Reader belongs
  pub remote_group_entity_id: EntityId,

  // See RTPS Spec v2.5 Section 8.4.10.4 on how the WriterProxy is supposed to
  // operate.
  // And 8.4.10.5 on statuses of the (cache) changes received from a writer.
  // The changes are identified by sequence numbers.
  // Any sequence number is at any moment in one of the following states:
  // unknown, missing, received, not_available.
  //
  // Unknown means that we have no information of that change. This is the initial state for
  // everyone. Missing means that writer claims to have it and reader may request it with
  // ACKNACK. Received means that the reader has received the change via DATA (or DATAFRAGs).
  // Not_available means that writer has informed via GAP message that change is not available.

  // Unknown can transition to Missing (via HEARTBEAT), Received (DATA), or not_available (GAP).
  // Missing can transition to Received or Not_available.
  // Received cannot transition to anything.
  // Not_available cannot transition to anything.

  // We keep a map "changes" and a sequence number counters "ack_base", to keep track of these.

  // changes.get(sn) is interpreted as follows:
  // * Some(Some(timestamp)) = received at timestamp
  // * Some(None) = not_available
  // * None = any state, see below:
  //
  // All changes below ack_base are either received or not_available.
  // All changes above hb_last are unknown (if they are not in "changes" map)
  // All changes between ack_base and hb_last (inclusive) are missing.

  // Timestamps are stored, because they are used as keys into the DDS Cache.
  changes: BTreeMap<SequenceNumber, Option<Timestamp>>,

  // The changes map is cleaned on heartbeat messages. The changes no longer available are dropped.
  pub received_heartbeat_count: i32,

  pub sent_ack_nack_count: i32,

  ack_base: SequenceNumber, // We can ACK everything before this number.
  // ack_base can be increased from N-1 to N, if we receive DATA with SequenceNumber N-1
  // heartbeat(first,last) => ack_base can be increased to first.
  // GAP is treated like receiving a message.

  // These are used for quick tracking of
  last_received_sequence_number: SequenceNumber,
  last_received_timestamp: Timestamp,

  // tracer_calib patch: the vendor of the remote writer's participant (its SPDP
  // announcement's PID_VENDORID), VENDOR_UNKNOWN if not known. It decides the form
  // of the preemptive ACKNACK (`Reader::send_preemptive_acknack_to`).
  pub remote_vendor_id: VendorId,

  // tracer_calib patch: the first and the newest sequence number seen in a DATA or
  // DATA_FRAG of this writer, and when a gap below a newer sample was last NACKed
  // (`gap_to_nack`, `Reader::nack_gap_below`).
  first_seen: Option<SequenceNumber>,
  newest_seen: SequenceNumber,
  gap_nacked_at: Option<std::time::Instant>,
  // tracer_calib patch: when this writer was last heard of (DATA, DATA_FRAG, HEARTBEAT,
  // GAP) or last asked for a HEARTBEAT (`Reader::poll_quiet_writers`).
  pub last_heard: Option<std::time::Instant>,
  // tracer_calib patch: the largest sample (serialized bytes) seen from this writer, 0
  // before the first, and the newest sequence number a request has named; they size a
  // repair request (`repair_slice`).
  largest_sample: usize,
  named_up_to: SequenceNumber,
}

impl RtpsWriterProxy {
  pub fn new(
    remote_writer_guid: GUID,
    unicast_locator_list: Vec<Locator>,
    multicast_locator_list: Vec<Locator>,
    remote_group_entity_id: EntityId,
  ) -> Self {
    Self {
      remote_writer_guid,
      unicast_locator_list,
      multicast_locator_list,
      remote_group_entity_id,
      changes: BTreeMap::new(),
      received_heartbeat_count: 0,
      sent_ack_nack_count: 0,
      // Sequence numbering must start at 1.
      // Therefore, we can ACK all sequence numbers below 1 even before receiving anything.
      ack_base: SequenceNumber::new(1),
      last_received_sequence_number: SequenceNumber::new(0),
      last_received_timestamp: Timestamp::INVALID,
      remote_vendor_id: VendorId::VENDOR_UNKNOWN, // tracer_calib patch
      first_seen: None,                             // tracer_calib patch
      newest_seen: SequenceNumber::new(0),          // tracer_calib patch
      gap_nacked_at: None,                          // tracer_calib patch
      largest_sample: 0,                            // tracer_calib patch
      named_up_to: SequenceNumber::new(0),          // tracer_calib patch
      last_heard: None,                             // tracer_calib patch
    }
  }

  // tracer_calib patch: begin (a gap below a newer sample is NACKed at once)
  /// What to ask this writer for now that its sample `sn` has arrived (in a DATA or
  /// DATA_FRAG), at `now`: the sequence numbers still missing between the first
  /// sample seen from it and `sn`, when `sn` opens a new gap (it is beyond the newest
  /// seen + 1), or when older ones are still missing `repeat` after they were last
  /// asked for (the request or its repair was lost too). Empty otherwise, and for the
  /// first sample seen: what comes before it is the HEARTBEAT's to say (a volatile
  /// reader that matched mid-stream does not ask for history).
  pub fn gap_to_nack(
    &mut self,
    sn: SequenceNumber,
    now: std::time::Instant,
    repeat: std::time::Duration,
  ) -> Vec<SequenceNumber> {
    self.last_heard = Some(now);
    let Some(first_seen) = self.first_seen else {
      self.first_seen = Some(sn);
      self.newest_seen = sn;
      return vec![];
    };
    let new_gap = sn > self.newest_seen.plus_1();
    self.newest_seen = max(self.newest_seen, sn);
    let due = self.gap_nacked_at.is_none_or(|at| now >= at + repeat);
    if !new_gap && !due {
      return vec![];
    }
    let from = max(first_seen, self.ack_base);
    let missing = self.missing_seqnums(from, sn - SequenceNumber::new(1));
    if !missing.is_empty() {
      self.gap_nacked_at = Some(now);
    }
    missing
  }

  /// The reader has just asked, at `now`, for what a HEARTBEAT up to `last` showed
  /// missing, from `first_missing` on: those sequence numbers are this reader's
  /// stream, so a later sample asks for them again if they are still missing
  /// (`gap_to_nack`), GAP_NACK_REPEAT after this request; a sample beyond `last` opens
  /// a new gap. Without it a sample lost before the first one seen (the request's
  /// repair lost too) waited for the writer's next HEARTBEAT, every later sample held
  /// back behind it: a first scan's contour 2-3 s late under 10 % loss (Fast DDS
  /// repeats its HEARTBEAT every 3 s).
  pub fn note_nacked(
    &mut self,
    first_missing: SequenceNumber,
    last: SequenceNumber,
    now: std::time::Instant,
  ) {
    self.first_seen = Some(self.first_seen.map_or(first_missing, |first| min(first, first_missing)));
    self.newest_seen = max(self.newest_seen, last);
    self.gap_nacked_at = Some(now);
  }
  // tracer_calib patch: end

  /// tracer_calib patch: what is still missing of this writer's stream (from the first
  /// sample seen to the newest seen or announced by a HEARTBEAT), to be asked for again
  /// at `now` because the last request is `repeat` old and no later sample has come to
  /// ask (`gap_to_nack`). Empty when nothing is missing or it is not due yet.
  pub fn still_missing_to_nack(
    &mut self,
    now: std::time::Instant,
    repeat: std::time::Duration,
  ) -> Vec<SequenceNumber> {
    if self.gap_nacked_at.is_some_and(|at| now < at + repeat) {
      return vec![];
    }
    let missing = self.still_missing();
    if !missing.is_empty() {
      self.gap_nacked_at = Some(now);
    }
    missing
  }

  /// tracer_calib patch: when `still_missing_to_nack` falls due, if something of this
  /// writer's stream is missing.
  pub fn still_missing_due(&self, repeat: std::time::Duration) -> Option<std::time::Instant> {
    let at = self.gap_nacked_at?;
    (!self.still_missing().is_empty()).then_some(at + repeat)
  }

  // What is missing of this writer's stream, from the first sample seen to the newest
  // seen or announced (none before a first sample).
  fn still_missing(&self) -> Vec<SequenceNumber> {
    self.first_seen.map_or_else(Vec::new, |first_seen| {
      self.missing_seqnums(max(first_seen, self.ack_base), self.newest_seen)
    })
  }

  /// tracer_calib patch: a sample of `bytes` (serialized) arrived from this writer, whole
  /// (`Reader::process_received_data`: a DATA, or the last DATA_FRAG of a sample).
  pub fn note_sample_size(&mut self, bytes: usize) {
    self.largest_sample = max(self.largest_sample, bytes);
  }

  /// tracer_calib patch: the first of `missing` (in order) that one repair request names.
  /// A first request names them all. A request that names again a sample asked for before
  /// (its repair, or the request, was lost) names as many as fit in `REPAIR_REQUEST_BYTES`
  /// at the largest sample seen from this writer, at least one. A writer answers an
  /// ACKNACK with the repairs it names; Fast DDS packs them into one datagram, which a link
  /// with an Ethernet MTU carries as IP fragments, lost whole when any one is. Naming
  /// every missing sample again and again fed a spiral: the more were missing, the larger
  /// the repair and the less likely to arrive (a Fast DDS driver's 3.2 kB scans under 10 %
  /// frame loss: repairs of 9-11 scans, 21-25 frames, each arriving about one time in ten,
  /// until the writer's keep-last history dropped them). The set an ACKNACK carries may
  /// leave missing ones out (RTPS 2.5, 8.3.7.1: a sequence number not in the set is
  /// undetermined); the next request names them once the first have come. A reader
  /// catching up on a history it has never asked for is not slowed.
  pub fn repair_slice(&mut self, mut missing: Vec<SequenceNumber>) -> Vec<SequenceNumber> {
    let again = missing.first().is_some_and(|first| *first <= self.named_up_to);
    if again && self.largest_sample > 0 {
      missing.truncate(max(1, REPAIR_REQUEST_BYTES / self.largest_sample));
    }
    if let Some(&last) = missing.last() {
      self.named_up_to = max(self.named_up_to, last);
    }
    missing
  }

  // tracer_calib patch: the remote participant's vendor (see `remote_vendor_id`).
  pub fn with_vendor_id(mut self, vendor_id: VendorId) -> Self {
    self.remote_vendor_id = vendor_id;
    self
  }

  pub fn next_ack_nack_sequence_number(&mut self) -> i32 {
    let c = self.sent_ack_nack_count;
    self.sent_ack_nack_count += 1;
    c
  }

  // Returns a bound, below which everything can be acknowledged, i.e.
  // is received either as DATA or GAP
  pub fn all_ackable_before(&self) -> SequenceNumber {
    self.ack_base
  }

  pub fn update_contents(&mut self, other: Self) {
    self.unicast_locator_list = other.unicast_locator_list;
    self.multicast_locator_list = other.multicast_locator_list;
    self.remote_group_entity_id = other.remote_group_entity_id;
    // tracer_calib patch: keep a known vendor
    if other.remote_vendor_id != VendorId::VENDOR_UNKNOWN {
      self.remote_vendor_id = other.remote_vendor_id;
    }
  }

  // This is used to check for DEADLINE policy
  pub fn last_change_timestamp(&self) -> Option<Timestamp> {
    if self.last_received_sequence_number > SequenceNumber::new(0) {
      Some(self.last_received_timestamp)
    } else {
      None
    }
  }

  // Check if we no samples in the received state.
  pub fn no_changes_received(&self) -> bool {
    self.ack_base == SequenceNumber::new(0) && self.changes.is_empty()
  }

  // Given an availability range from a HEARTBEAT, find out what we are missing.
  //
  // Note: Heartbeat gives bounds only. Some samples within that range may
  // have been received already, or not really available, i.e. there may be GAPs
  // in the range.
  pub fn missing_seqnums(
    &self,
    hb_first_sn: SequenceNumber,
    hb_last_sn: SequenceNumber,
  ) -> Vec<SequenceNumber> {
    // Need to verify first <= last, or BTreeMap::range will crash
    if hb_first_sn > hb_last_sn {
      if hb_first_sn > hb_last_sn + SequenceNumber::from(1) {
        warn!("Negative range of missing_seqnums first={hb_first_sn:?} last={hb_last_sn:?}");
      } else {
        // first == last+1
        // This is normal. See RTPS 2.5 Spec Section "8.3.8.6.3 Validity"
        // It means nothing is available. Since nothing is available, nothing is
        // missing.
      }
      return vec![];
    }

    let mut missing_seqnums = Vec::with_capacity(32); // out of hat value

    let relevant_interval = SequenceNumber::range_inclusive(
      max(hb_first_sn, self.ack_base), // ignore those that we already have
      hb_last_sn,
    );

    // iterator over known Received and Not_available changes.
    let known =
      // again check for negative intervals, or BTreeMap::range will crash
      if relevant_interval.begin() <= relevant_interval.end() {
        self.changes
          .range( relevant_interval )
          .map(|e| *e.0)
          .collect()
      } else { vec![] };
    let mut known_iter = known.iter();
    let mut known_head = known_iter.next();

    // Iterate over all SequenceNumbers (indices) in the advertised range.
    for s in relevant_interval {
      match known_head {
        None => missing_seqnums.push(s), // no known changes left => s is missing
        Some(known_sn) => {
          // there are known changes left
          if *known_sn == s {
            // and the index sequence matches it => not missing
            // => advance to next known change and continue iteration
            known_head = known_iter.next();
          } else {
            // but it is not yet this index s => s is missing
            missing_seqnums.push(s);
          }
        }
      }
    }

    missing_seqnums
  }

  // Check if we have already received this sequence number
  // or it has been marked as not_available
  pub fn should_ignore_change(&self, seqnum: SequenceNumber) -> bool {
    seqnum < self.ack_base || self.changes.contains_key(&seqnum)
  }

  // This is used to mark DATA as received.
  pub fn received_changes_add(&mut self, seq_num: SequenceNumber, receive_timestamp: Timestamp) {
    self.changes.insert(seq_num, Some(receive_timestamp));

    // Update deadline tracker
    if seq_num > self.last_received_sequence_number {
      self.last_received_sequence_number = seq_num;
      self.last_received_timestamp = receive_timestamp;
    }

    // We get to advance ack_base if it was equal to seq_num
    // If ack_base < seq_num, we are still missing seq_num-1 or others below
    // If ack_base > seq_num, this is either a duplicate or ack_base was wrong.
    // Remember, ack_base is the SN one past the last received/irrelevant SN.
    if seq_num == self.ack_base {
      self.advance_ack_base();
    }

    // Bound the map even when ack_base cannot advance (best-effort loss leaves a
    // permanent gap below the newly received sample).
    self.enforce_change_map_cap();
  }

  // Used to add individual irrelevant changes from GAP message
  pub fn set_irrelevant_change(&mut self, seq_num: SequenceNumber) {
    // If sequence number is still in the relevant range,
    // insert not_available marker
    if seq_num >= self.ack_base {
      self.changes.insert(seq_num, None);
    }

    if seq_num == self.ack_base {
      // ack_base can be advanced
      self.advance_ack_base();
    }
  }

  // Used to add range of irrelevant changes from GAP submessage or unavailable
  // changes from HEARTBEAT submessage
  pub fn irrelevant_changes_range(
    &mut self,
    remove_from: SequenceNumber,
    remove_until_before: SequenceNumber,
  ) {
    // check sanity
    if remove_from > remove_until_before {
      error!(
        "irrelevant_changes_range: negative range: remove_from={remove_from:?} \
         remove_until_before={remove_until_before:?}"
      );
      return;
    }
    // now remove_from <= remove_until_before, i.e. at least zero to remove
    //
    // Two cases here:
    // If remove_from <= self.ack_base, then we may proceed by moving
    // ack_base to remove_until_before and clearing "changes" before that.
    //
    // Else (remove_from > self.ack_base), which means we must insert not_available
    // markers to "changes".
    //
    if remove_from <= self.ack_base {
      let mut removed_and_after = self.changes.split_off(&remove_from);
      let mut after = removed_and_after.split_off(&remove_until_before);
      // let removed = removed_and_after;
      self.changes.append(&mut after);

      if remove_until_before > self.ack_base {
        // Move the base to skip the irrelevant changes
        self.ack_base = remove_until_before;
        // The new base might be a sample that we already have, move the base forward
        // until we hit a missing one
        self.advance_ack_base();
      }

      debug!(
        "ack_base increased to {:?} by irrelevant_changes_range {:?} to {:?}. writer={:?}",
        self.ack_base, remove_from, remove_until_before, self.remote_writer_guid
      );
    } else {
      // TODO: This potentially generates a very large BTreeMap
      for na in
        SequenceNumber::range_inclusive(remove_from, remove_until_before - SequenceNumber::new(1))
      {
        self.changes.insert(na, None);
      }
      self.enforce_change_map_cap();
    }
  }

  // Used to mark messages irrelevant because of a HEARTBEAT message.
  //
  // smallest_seqnum is the lowest key to be retained
  pub fn irrelevant_changes_up_to(&mut self, smallest_seqnum: SequenceNumber) {
    self.irrelevant_changes_range(SequenceNumber::new(0), smallest_seqnum);
  }

  fn discovered_or_default(drd: &[Locator], default: &[Locator]) -> Vec<Locator> {
    if drd.is_empty() {
      default.to_vec()
    } else {
      drd.to_vec()
    }
  }

  pub fn from_discovered_writer_data(
    discovered_writer_data: &DiscoveredWriterData,
    default_unicast_locators: &[Locator],
    default_multicast_locators: &[Locator],
  ) -> RtpsWriterProxy {
    let unicast_locator_list = Self::discovered_or_default(
      &discovered_writer_data.writer_proxy.unicast_locator_list,
      default_unicast_locators,
    );
    let multicast_locator_list = Self::discovered_or_default(
      &discovered_writer_data.writer_proxy.multicast_locator_list,
      default_multicast_locators,
    );

    RtpsWriterProxy {
      remote_writer_guid: discovered_writer_data.writer_proxy.remote_writer_guid,
      remote_group_entity_id: EntityId::UNKNOWN,
      unicast_locator_list,
      multicast_locator_list,
      changes: BTreeMap::new(),
      received_heartbeat_count: 0,
      sent_ack_nack_count: 0,
      ack_base: SequenceNumber::default(),
      last_received_sequence_number: SequenceNumber::new(0),
      last_received_timestamp: Timestamp::INVALID,
      remote_vendor_id: VendorId::VENDOR_UNKNOWN, // tracer_calib patch
      first_seen: None,                             // tracer_calib patch
      newest_seen: SequenceNumber::new(0),          // tracer_calib patch
      gap_nacked_at: None,                          // tracer_calib patch
      largest_sample: 0,                            // tracer_calib patch
      named_up_to: SequenceNumber::new(0),          // tracer_calib patch
      last_heard: None,                             // tracer_calib patch
    }
  } // fn

  // Advance ack_base as far as possible
  // This function should be called after the writer proxy has modified its
  // changes cache (for instance added a new received change) such that ack_base
  // could be advanced
  fn advance_ack_base(&mut self) {
    // Start searching from current ack_base
    let mut test_sn = self.ack_base;

    for (&sn, _what) in self.changes.range((Included(&self.ack_base), Unbounded)) {
      if sn == test_sn {
        // test_sn found from changes, ack_base can be set to test_sn + 1
        test_sn = test_sn + SequenceNumber::new(1);
      } else {
        // test_sn not found from changes, stop here
        break;
      }

      // The changes cache contains a string of consecutive sequence numbers from
      // ack_base-1 up to test_sn (excluded), so ack_base can be set to test_sn
      self.ack_base = test_sn;
    }

    // Entries strictly below ack_base are already accounted for (received or
    // not_available) and are never read again: `missing_seqnums` starts at
    // max(hb_first, ack_base) and `should_ignore_change` treats anything below
    // ack_base as handled regardless of the map. Historically these entries were
    // only cleaned by HEARTBEAT/GAP, which best-effort writers never send, so
    // the map grew by one entry per received sample. Drop them eagerly here.
    self.prune_below_ack_base();
  }

  // Drop tracked changes below ack_base (they are already accounted for).
  fn prune_below_ack_base(&mut self) {
    // Only touch the map when there is actually something below ack_base to drop
    // (the common stalled-gap case has nothing below ack_base, so we skip the
    // split_off entirely and keep the receive path cheap).
    if matches!(self.changes.keys().next(), Some(&first) if first < self.ack_base) {
      // split_off returns everything from the key onward; keep that, drop the rest.
      self.changes = self.changes.split_off(&self.ack_base);
    }
  }

  // Memory-safety backstop: under best-effort loss `ack_base` can stall at a
  // permanently missing sample while received sequence numbers pile up above it,
  // so pruning below ack_base is not enough. When the map exceeds the cap, force
  // ack_base past the oldest tracked change (giving up on the stalled gap as
  // lost) so the map cannot grow without bound.
  fn enforce_change_map_cap(&mut self) {
    while self.changes.len() > MAX_TRACKED_CHANGES_PER_WRITER {
      let oldest = match self.changes.keys().next() {
        Some(&sn) => sn,
        None => break,
      };
      self.changes.remove(&oldest);
      if self.ack_base <= oldest {
        self.ack_base = oldest + SequenceNumber::new(1);
      }
    }
    // After forcing ack_base forward, drop anything now below it.
    self.prune_below_ack_base();
  }

  #[cfg(test)]
  pub fn tracked_changes_count(&self) -> usize {
    self.changes.len()
  }
} // impl

#[cfg(test)]
mod bounded_map_tests {
  use super::*;
  use crate::structure::guid::GuidPrefix;

  fn test_proxy() -> RtpsWriterProxy {
    RtpsWriterProxy::new(
      GUID::new(GuidPrefix::UNKNOWN, EntityId::UNKNOWN),
      vec![],
      vec![],
      EntityId::UNKNOWN,
    )
  }

  // tracer_calib patch: a sample lost before the first one seen, asked for when a
  // HEARTBEAT showed it, is asked for again by a later sample (`note_nacked`).
  #[test]
  fn a_later_sample_asks_again_for_what_a_heartbeat_showed_missing() {
    let now = std::time::Instant::now();
    let repeat = std::time::Duration::from_millis(25);
    let later = now + std::time::Duration::from_secs(1);
    let sn = SequenceNumber::new;

    // Without the HEARTBEAT's request the first sample seen asks for nothing before it.
    let mut wp = test_proxy();
    assert!(wp.gap_to_nack(sn(2), later, repeat).is_empty());

    // HEARTBEAT 1..1, sample 1 missing and asked for; its repair is lost.
    let mut wp = test_proxy();
    wp.note_nacked(sn(1), sn(1), now);
    // Sample 2 right after the request: not asked again yet.
    assert!(wp.gap_to_nack(sn(2), now, repeat).is_empty());
    // Sample 3 a second later: sample 1 again.
    wp.received_changes_add(sn(2), Timestamp::INVALID);
    assert_eq!(wp.gap_to_nack(sn(3), later, repeat), vec![sn(1)]);
    // Beyond the HEARTBEAT's last, a new gap is asked for at once, with the old one.
    let mut wp = test_proxy();
    wp.note_nacked(sn(1), sn(1), now);
    assert_eq!(wp.gap_to_nack(sn(3), now, repeat), vec![sn(1), sn(2)]);
  }

  // tracer_calib patch: samples known missing are asked for again while the writer is
  // quiet, each `repeat` after the last request (`still_missing_to_nack`), until they
  // arrive; nothing is asked before one is known missing.
  #[test]
  fn a_quiet_writer_is_asked_again_for_what_is_still_missing() {
    let now = std::time::Instant::now();
    let repeat = std::time::Duration::from_millis(100);
    let ms = std::time::Duration::from_millis;
    let sn = SequenceNumber::new;

    let mut wp = test_proxy();
    assert!(wp.still_missing_to_nack(now, repeat).is_empty());
    assert_eq!(wp.still_missing_due(repeat), None);

    // Samples 1 and 3 received, 2 lost: asked for when 3 came.
    wp.received_changes_add(sn(1), Timestamp::INVALID);
    assert!(wp.gap_to_nack(sn(1), now, repeat).is_empty());
    wp.received_changes_add(sn(3), Timestamp::INVALID);
    assert_eq!(wp.gap_to_nack(sn(3), now, repeat), vec![sn(2)]);
    // No later sample comes. Not again before `repeat`; then at each `repeat`.
    assert_eq!(wp.still_missing_due(repeat), Some(now + repeat));
    assert!(wp.still_missing_to_nack(now + ms(50), repeat).is_empty());
    assert_eq!(wp.still_missing_to_nack(now + ms(100), repeat), vec![sn(2)]);
    assert_eq!(wp.still_missing_due(repeat), Some(now + ms(200)));
    // A HEARTBEAT announced 4 as well, asked for: both, at the next due time.
    wp.note_nacked(sn(2), sn(4), now + ms(150));
    assert_eq!(wp.still_missing_to_nack(now + ms(250), repeat), vec![sn(2), sn(4)]);
    // Once they arrive, nothing more.
    wp.received_changes_add(sn(2), Timestamp::INVALID);
    wp.received_changes_add(sn(4), Timestamp::INVALID);
    assert!(wp.still_missing_to_nack(now + ms(400), repeat).is_empty());
    assert_eq!(wp.still_missing_due(repeat), None);
  }

  // tracer_calib patch: a first repair request names every missing sample; one that
  // names again a sample asked for before names as many as fit in REPAIR_REQUEST_BYTES at
  // the largest sample seen, at least one, the oldest first (`repair_slice`).
  #[test]
  fn a_repeated_repair_request_names_a_repairs_worth_of_samples() {
    let sn = SequenceNumber::new;
    let missing = |from: i64, to: i64| -> Vec<SequenceNumber> { (from..=to).map(sn).collect() };
    // Before a first sample: all of them, however often.
    let mut wp = test_proxy();
    assert_eq!(wp.repair_slice(missing(1, 20)), missing(1, 20));
    assert_eq!(wp.repair_slice(missing(1, 20)), missing(1, 20));
    // 3.2 kB scans: a first request for 1..20 names all; asked again, two.
    let mut wp = test_proxy();
    wp.note_sample_size(3200);
    assert_eq!(wp.repair_slice(missing(1, 20)), missing(1, 20));
    assert_eq!(wp.repair_slice(missing(1, 20)), missing(1, 2));
    // New samples missing beyond all that was named: named whole.
    assert_eq!(wp.repair_slice(missing(21, 30)), missing(21, 30));
    // The old ones still missing with new ones after: the oldest two.
    assert_eq!(wp.repair_slice(missing(3, 40)), missing(3, 4));
    // A larger sample seen since: one a request, however large.
    wp.note_sample_size(60_000);
    wp.note_sample_size(100);
    assert_eq!(wp.repair_slice(missing(3, 40)), missing(3, 3));
    // Small samples: REPAIR_REQUEST_BYTES / 100 of them, here all that is missing.
    let mut wp = test_proxy();
    wp.note_sample_size(100);
    assert_eq!(wp.repair_slice(missing(1, 20)), missing(1, 20));
    assert_eq!(wp.repair_slice(missing(1, 20)), missing(1, 20));
    assert!(wp.repair_slice(vec![]).is_empty());
  }

  // Regression: a best-effort writer sends no HEARTBEAT/GAP, so the changes map
  // used to accumulate one entry per received sample forever. With eager pruning
  // below ack_base, contiguous delivery must keep the map ~empty.
  #[test]
  fn changes_map_does_not_grow_on_contiguous_delivery() {
    let mut wp = test_proxy();
    let n: i64 = 50_000;
    for i in 1..=n {
      wp.received_changes_add(SequenceNumber::new(i), Timestamp::INVALID);
    }
    // Everything received in order: ack_base advanced past the last sample.
    assert_eq!(wp.all_ackable_before(), SequenceNumber::new(n + 1));
    assert!(
      wp.tracked_changes_count() <= 1,
      "changes map grew unbounded on contiguous delivery: {} entries",
      wp.tracked_changes_count()
    );
  }

  // Regression: with a permanently missing sample (best-effort loss) ack_base
  // stalls, so pruning below it is not enough. The hard cap must still bound the
  // map by giving up on the stalled gap.
  #[test]
  fn changes_map_bounded_with_permanent_gap() {
    let mut wp = test_proxy();
    // Sample 1 is never delivered; deliver a long run above it.
    let n: i64 = MAX_TRACKED_CHANGES_PER_WRITER as i64 * 4;
    for i in 2..=n {
      wp.received_changes_add(SequenceNumber::new(i), Timestamp::INVALID);
    }
    assert!(
      wp.tracked_changes_count() <= MAX_TRACKED_CHANGES_PER_WRITER,
      "changes map exceeded cap {} under a permanent gap: {} entries",
      MAX_TRACKED_CHANGES_PER_WRITER,
      wp.tracked_changes_count()
    );
  }
}
