#[cfg(any(feature = "mio_06", feature = "mio_1"))]
use std::io;

#[cfg(feature = "mio_06")]
use rustdds::mio::{Evented, Poll, PollOpt, Ready, Token};
#[cfg(feature = "mio_1")]
use rustdds::mio1;
use rustdds::{rpc::*, *};
#[allow(unused_imports)]
use log::{debug, error, info, warn};
use futures::{StreamExt, pin_mut, stream::FusedStream};
use std::{
  collections::{BTreeMap, BTreeSet},
  sync::{
    Arc, Mutex,
    atomic::{AtomicU64, Ordering},
  },
  time::{Duration, Instant},
};

use crate::{
  error::{CreateResult, ReadError, ReadResult, WriteError, WriteResult},
  message::Message,
  message_info::MessageInfo,
  node::Node,
  qos::QosProfile,
  service::*,
};

// --------------------------------------------
// --------------------------------------------
/// Server end of a ROS2 Service
pub struct Server<Req, Resp>
where
  Req: Message,
  Resp: Message,
{
  service_mapping: ServiceMapping,
  request_receiver: SimpleDataReaderR<RequestWrapper<Req>>,
  response_sender: DataWriterR<ResponseWrapper<Resp>>,
  // PATCH (tracer_calib): the node's map of local writers to the remote readers
  // matched with them, kept by the Spinner; see `write_options`.
  matched_readers: Arc<Mutex<BTreeMap<GUID, BTreeSet<GUID>>>>,
  // PATCH (tracer_calib): each request's layout, read from the wire, until it is
  // answered; see `decode_request` and `PendingLayouts`.
  pending: Mutex<PendingLayouts>,
  bad_requests: AtomicU64,
  bad_request_log: Mutex<BadRequestLog>,
  // PATCH (tracer_calib): to find a Cyclone DDS client's response reader from the
  // discovery data (see `cyclone_client_reader`), and what was found.
  participant: DomainParticipant,
  cyclone_readers: Mutex<BTreeMap<GUID, GUID>>,
}

/// PATCH (tracer_calib): the layout (and request writer) of each request taken and
/// not answered yet, so that its response goes out in the layout its client reads.
/// Bounded: a server that never answers some requests forgets the oldest ones
/// (their responses, if ever sent, use the server's own mapping).
#[derive(Default)]
struct PendingLayouts {
  by_id: BTreeMap<RmwRequestId, (u64, ServiceMapping, GUID)>,
  by_age: BTreeMap<u64, RmwRequestId>,
  next: u64,
}

impl PendingLayouts {
  const CAPACITY: usize = 4096;

  fn insert(&mut self, id: RmwRequestId, mapping: ServiceMapping, writer: GUID) {
    let n = self.next;
    self.next += 1;
    if let Some((old, ..)) = self.by_id.insert(id, (n, mapping, writer)) {
      self.by_age.remove(&old);
    }
    self.by_age.insert(n, id);
    while self.by_age.len() > Self::CAPACITY {
      if let Some((_, oldest)) = self.by_age.pop_first() {
        self.by_id.remove(&oldest);
      }
    }
  }

  fn take(&mut self, id: &RmwRequestId) -> Option<(ServiceMapping, GUID)> {
    let (n, mapping, writer) = self.by_id.remove(id)?;
    self.by_age.remove(&n);
    Some((mapping, writer))
  }
}

/// PATCH (tracer_calib): when each client that sent an unreadable request was last
/// warned about, and how many of its requests were not shown since.
#[derive(Default)]
struct BadRequestLog {
  clients: BTreeMap<GUID, (Instant, u64)>,
}

impl BadRequestLog {
  const INTERVAL: Duration = Duration::from_secs(60);
  const MAX_CLIENTS: usize = 1024;

  /// `Some(n)`: log now, `n` earlier ones from this client were not shown.
  fn allow(&mut self, client: GUID, now: Instant) -> Option<u64> {
    if !self.clients.contains_key(&client) && self.clients.len() >= Self::MAX_CLIENTS {
      self.clients.retain(|_, (t, _)| now.duration_since(*t) < Self::INTERVAL);
    }
    match self.clients.get_mut(&client) {
      Some((last, held)) if now.duration_since(*last) < Self::INTERVAL => {
        *held += 1;
        None
      }
      Some((last, held)) => {
        let n = *held;
        *last = now;
        *held = 0;
        Some(n)
      }
      None => {
        self.clients.insert(client, (now, 0));
        Some(0)
      }
    }
  }
}

impl<Req, Resp> Server<Req, Resp>
where
  Req: Message + 'static,
  Resp: Message + 'static,
{
  pub(crate) fn new(
    service_mapping: ServiceMapping,
    node: &mut Node,
    request_topic: &Topic,
    response_topic: &Topic,
    qos_request: Option<QosProfile>,
    qos_response: Option<QosProfile>,
  ) -> CreateResult<Self> {
    let request_receiver =
      node.create_request_reader // PATCH (tracer_calib): with a latency budget
      ::<RequestWrapper<Req>, ServiceDeserializerAdapter<RequestWrapper<Req>>>(
        request_topic, qos_request)?;
    let response_sender = node
      .create_datawriter::<ResponseWrapper<Resp>, ServiceSerializerAdapter<ResponseWrapper<Resp>>>(
        response_topic,
        qos_response,
      )?;

    debug!(
      "Created new Server: requests={} response={}",
      request_topic.name(),
      response_topic.name()
    );

    Ok(Server::<Req, Resp> {
      service_mapping,
      request_receiver,
      response_sender,
      matched_readers: node.writers_to_remote_readers(),
      pending: Mutex::new(PendingLayouts::default()),
      bad_requests: AtomicU64::new(0),
      bad_request_log: Mutex::new(BadRequestLog::default()),
      participant: node.domain_participant(),
      cyclone_readers: Mutex::new(BTreeMap::new()),
    })
  }

  /// PATCH (tracer_calib): how many requests fitted no layout (not answered).
  pub fn bad_request_count(&self) -> u64 {
    self.bad_requests.load(Ordering::Relaxed)
  }

  /// PATCH (tracer_calib): a request in the layout its client used, decided per
  /// request from the wire (`RequestWrapper::unwrap_per_request`): a server
  /// answers Fast DDS (Enhanced) and Cyclone DDS clients at once, whatever
  /// `ServiceMapping` it was made with (that one is tried first for other vendors).
  /// The layout is kept for the response. A request that fits no layout is an
  /// error, counted (`bad_request_count`) and logged once a minute per client at
  /// most; the server carries on with the next request.
  fn decode_request(
    &self,
    req_wrapper: RequestWrapper<Req>,
    mi: &MessageInfo,
  ) -> ReadResult<(RmwRequestId, Req)> {
    let writer = GUID::from(mi.publisher_gid());
    match req_wrapper.unwrap_per_request(self.service_mapping, mi) {
      Ok((id, req, mapping)) => {
        debug!("request {id:?} from writer {writer:?}: {mapping:?} layout");
        self.pending.lock().unwrap().insert(id, mapping, writer);
        Ok((id, req))
      }
      Err(e) => {
        let total = self.bad_requests.fetch_add(1, Ordering::Relaxed) + 1;
        let allowed = self.bad_request_log.lock().unwrap().allow(writer, Instant::now());
        if let Some(held) = allowed {
          warn!(
            "service {}: not answered: {e} ({total} unreadable requests so far; {held} more \
             from this client not shown; at most one a minute per client is)",
            self.response_sender.topic().name()
          );
        }
        Err(e)
      }
    }
  }

  /// PATCH (tracer_calib): the response in the layout of its request.
  fn response_wrapper(
    &self,
    rmw_req_id: RmwRequestId,
    response: Resp,
  ) -> WriteResult<(ResponseWrapper<Resp>, WriteOptions), ()> {
    let (mapping, writer) = self
      .pending
      .lock()
      .unwrap()
      .take(&rmw_req_id)
      .unwrap_or((self.service_mapping, GUID::GUID_UNKNOWN));
    let waited = self.wait_for_client_reader(rmw_req_id, mapping, writer);
    let resp_wrapper =
      ResponseWrapper::<Resp>::new(mapping, rmw_req_id, RepresentationIdentifier::CDR_LE, response)?;
    Ok((
      resp_wrapper,
      self.write_options(rmw_req_id, mapping, writer, &waited),
    ))
  }

  /// PATCH (tracer_calib): how long a response waits for its client's response reader
  /// to be matched (`wait_for_client_reader`). Long enough for that reader's
  /// announcement to be repaired on a lossy network (under 25 % UDP loss, 500 ms lost
  /// the first calls of new clients); the common case, a reader matched already, does
  /// not wait at all.
  const CLIENT_READER_WAIT: Duration = Duration::from_millis(3000);

  /// PATCH (tracer_calib): wait, at most `CLIENT_READER_WAIT`, until our response
  /// writer has matched the response reader of the client that sent `rmw_req_id`.
  ///
  /// A client sends its first request as soon as it has matched our request reader
  /// and response writer, which says nothing about whether we have matched its
  /// response reader yet: the two sides discover each other on their own. A response
  /// written before that (a VOLATILE writer) never reaches the client, which waits
  /// for good. rmw_cyclonedds_cpp and rmw_fastrtps_cpp servers wait 100 ms for the
  /// client's reader for the same reason (`rmw_send_response`); this waits longer,
  /// since the alternative is a lost response. The reader is the one a Fast DDS
  /// client names in the request (Enhanced: `writer_gid`, when it is a reader's); for
  /// a Cyclone DDS client (a client id, not a GUID, in the request), a reader of the
  /// requesting participant. Other requests do not wait, nor does a reader already
  /// matched (the common case: a check under the send buffer's lock). Returns the
  /// readers waited for that are matched (RustDDS' own record, which the Spinner's
  /// map and the discovery data may not show yet: see `write_options`).
  fn wait_for_client_reader(
    &self,
    rmw_req_id: RmwRequestId,
    mapping: ServiceMapping,
    request_writer: GUID,
  ) -> Vec<GUID> {
    let start = std::time::Instant::now();
    let matched = match mapping {
      ServiceMapping::Enhanced => {
        let reader = GUID::from(rmw_req_id.writer_gid);
        if !reader.entity_id.entity_kind.is_reader() {
          return Vec::new();
        }
        self
          .response_sender
          .wait_for_matched_reader(|r| r == reader, Self::CLIENT_READER_WAIT)
      }
      ServiceMapping::Cyclone if request_writer != GUID::GUID_UNKNOWN => {
        let prefix = request_writer.prefix;
        self
          .response_sender
          .wait_for_matched_reader(|r| r.prefix == prefix, Self::CLIENT_READER_WAIT)
      }
      _ => return Vec::new(),
    };
    let waited = start.elapsed();
    if matched.is_empty() {
      debug!(
        "response to {rmw_req_id:?}: the client's response reader is not matched after {:?}",
        Self::CLIENT_READER_WAIT
      );
    } else if waited >= std::time::Duration::from_millis(1) {
      debug!("response to {rmw_req_id:?}: the client's response reader matched after {waited:?}");
    }
    matched
  }

  /// PATCH (tracer_calib): the response reader of the Cyclone DDS client whose
  /// request writer is `writer`, if it is matched with our response writer.
  /// rmw_cyclonedds_cpp gives a client's request writer and response reader the same
  /// `clientid=...;` in their USER_DATA (its own servers pair them the same way); found
  /// once per client from the discovery data, then kept while it stays matched.
  fn cyclone_client_reader(&self, writer: GUID, matched: &BTreeSet<GUID>) -> Option<GUID> {
    let mut known = self.cyclone_readers.lock().unwrap();
    if let Some(reader) = known.get(&writer).filter(|r| matched.contains(r)) {
      return Some(*reader);
    }
    let client_id = |user_data: &[u8]| -> Option<Vec<u8>> {
      let at = user_data.windows(9).position(|w| w == b"clientid=")? + 9;
      let len = user_data[at..].iter().position(|&b| b == b';')?;
      Some(user_data[at..at + len].to_vec())
    };
    let id = self
      .participant
      .discovered_writers()
      .into_iter()
      .find(|w| w.writer_proxy.remote_writer_guid == writer)
      .and_then(|w| client_id(&w.user_data))?;
    let topic = self.response_sender.topic().name();
    let reader = self
      .participant
      .discovered_readers()
      .into_iter()
      .find(|r| {
        matched.contains(&r.reader_proxy.remote_reader_guid)
          && *r.subscription_topic_data.topic_name() == topic
          && client_id(&r.user_data).as_ref() == Some(&id)
      })?
      .reader_proxy
      .remote_reader_guid;
    if known.len() >= 1024 {
      known.retain(|_, r| matched.contains(r));
    }
    known.insert(writer, reader);
    Some(reader)
  }

  /// PATCH (tracer_calib): the write options of a response, sent to the requesting
  /// client's reader alone when it is known.
  ///
  /// A Fast DDS client (rmw_fastrtps since ros2/rmw_fastrtps#390) puts the GUID of its
  /// response reader in the request's related sample identity, the `writer_gid` of
  /// `rmw_req_id` here. Sent to every matched reader, each response reaches every
  /// client of the service; a client's reply queue (KEEP_LAST 10 by default) then
  /// fills with other clients' replies in a burst, and its own are dropped. When that
  /// GUID is a reader matched with our response writer, the response goes to it
  /// alone (the others get a GAP); otherwise (other vendors, a match not seen yet)
  /// to all, as before.
  ///
  /// `waited`: the client's readers RustDDS has matched (`wait_for_client_reader`).
  /// RustDDS can match a reader from its announcement before Discovery has read it
  /// (`vendor/rustdds/PATCHES.md`), so before the Spinner's map and the discovery
  /// data show it: then that reader is taken (for a Cyclone DDS client, if it is the
  /// only one of its participant).
  fn write_options(
    &self,
    rmw_req_id: RmwRequestId,
    mapping: ServiceMapping,
    request_writer: GUID,
    waited: &[GUID],
  ) -> WriteOptions {
    let options = WriteOptionsBuilder::new()
      .source_timestamp(Timestamp::now()) // always add source timestamp
      // TODO: Check if this is right. Cyclone mapping does not send
      // Related Sample Identity in
      // WriteOptions (QoS ParameterList), but within data payload.
      // But maybe it is not harmful to send it in both?
      .related_sample_identity(SampleIdentity::from(rmw_req_id));
    let matched_readers = self.matched_readers.lock().unwrap();
    let no_readers = BTreeSet::new();
    let matched = matched_readers
      .get(&self.response_sender.guid())
      .unwrap_or(&no_readers);
    // PATCH (tracer_calib): per layout; a Cyclone DDS client's reader is found by its
    // client id (`cyclone_client_reader`), else as waited for.
    let only_waited = match waited {
      [reader] => Some(*reader),
      _ => None,
    };
    let client_reader = match mapping {
      ServiceMapping::Enhanced => Some(GUID::from(rmw_req_id.writer_gid))
        .filter(|reader| matched.contains(reader) || waited.contains(reader)),
      ServiceMapping::Cyclone => self
        .cyclone_client_reader(request_writer, matched)
        .or(only_waited),
      ServiceMapping::Basic => None,
    };
    debug!("response to {rmw_req_id:?} ({mapping:?}): to reader {client_reader:?} (None: all)");
    match client_reader {
      Some(reader) => options.to_single_reader(reader).build(),
      None => options.build(),
    }
  }

  /// Receive a request from Client.
  /// Returns `Ok(None)` if no new requests have arrived.
  pub fn receive_request(&self) -> ReadResult<Option<(RmwRequestId, Req)>> {
    self.request_receiver.drain_read_notifications();
    let dcc_rw: Option<no_key::DeserializedCacheChange<RequestWrapper<Req>>> =
      self.request_receiver.try_take_one()?;

    match dcc_rw {
      None => Ok(None),
      Some(dcc) => {
        let mi = MessageInfo::from(&dcc);
        let req_wrapper = dcc.into_value();
        let (ri, req) = self.decode_request(req_wrapper, &mi)?; // PATCH (tracer_calib)
        Ok(Some((ri, req)))
      }
    } // match
  }

  /// Send response to request by Client.
  /// rmw_req_id identifies request being responded.
  pub fn send_response(&self, rmw_req_id: RmwRequestId, response: Resp) -> WriteResult<(), ()> {
    // PATCH (tracer_calib): in the layout of the request
    let (resp_wrapper, write_opts) = self.response_wrapper(rmw_req_id, response)?;
    self
      .response_sender
      .write_with_options(resp_wrapper, write_opts)
      .map(|_| ())
      .map_err(|e| WriteError::from(e.forget_data())) // lose SampleIdentity
    // result
  }

  /// The request_id must be sent back with the response to identify which
  /// request and response belong together.
  pub async fn async_receive_request(&self) -> ReadResult<(RmwRequestId, Req)> {
    let dcc_stream = self.request_receiver.as_async_stream();
    pin_mut!(dcc_stream);

    match dcc_stream.next().await {
      Some(Err(e)) => Err(e.into()),
      Some(Ok(dcc)) => {
        let mi = MessageInfo::from(&dcc);
        let req_wrapper = dcc.into_value();
        let (ri, req) = self.decode_request(req_wrapper, &mi)?; // PATCH (tracer_calib)
        debug!("async_receive_request: {ri:?}");
        Ok((ri, req))
      }
      // This should never occur, because topic do not "end".
      None => read_error_internal!("SimpleDataReader value stream unexpectedly ended!"),
    } // match
  }

  /// Returns a never-ending stream of (request_id, request)
  /// The request_id must be sent back with the response to identify which
  /// request and response belong together.
  pub fn receive_request_stream(
    &self,
  ) -> impl FusedStream<Item = ReadResult<(RmwRequestId, Req)>> + '_ {
    Box::pin(self.request_receiver.as_async_stream().then(
      move |dcc_r| async move {
        match dcc_r {
          Err(e) => Err(e.into()),
          Ok(dcc) => {
            let mi = MessageInfo::from(&dcc);
            let req_wrapper = dcc.into_value();
            debug!("receive_request_stream: messageinfo={mi:?}");
            self.decode_request(req_wrapper, &mi) // PATCH (tracer_calib)
          }
        } // match
      }, // async
    ))
  }

  /// Asynchronous response sending
  pub async fn async_send_response(
    &self,
    rmw_req_id: RmwRequestId,
    response: Resp,
  ) -> WriteResult<(), ()> {
    // PATCH (tracer_calib): in the layout of the request
    let (resp_wrapper, write_opts) = self.response_wrapper(rmw_req_id, response)?;
    debug!("async_send_response: rmw_req_id = {rmw_req_id:?}");
    debug!(
      "async_send_response: related_sample_identity = {:?}",
      SampleIdentity::from(rmw_req_id)
    );
    self
      .response_sender
      .async_write_with_options(resp_wrapper, write_opts)
      .await
      .map(|_| ())
      .map_err(|e| WriteError::from(e.forget_data())) // lose SampleIdentity
    // result
  }
}

#[cfg(feature = "mio_06")]
impl<Req, Resp> Evented for Server<Req, Resp>
where
  Req: Message + 'static,
  Resp: Message + 'static,
{
  fn register(&self, poll: &Poll, token: Token, interest: Ready, opts: PollOpt) -> io::Result<()> {
    self.request_receiver.register(poll, token, interest, opts)
  }

  fn reregister(
    &self,
    poll: &Poll,
    token: Token,
    interest: Ready,
    opts: PollOpt,
  ) -> io::Result<()> {
    self
      .request_receiver
      .reregister(poll, token, interest, opts)
  }

  fn deregister(&self, poll: &Poll) -> io::Result<()> {
    self.request_receiver.deregister(poll)
  }
}

#[cfg(feature = "mio_1")]
impl<Req, Resp> mio1::event::Source for Server<Req, Resp>
where
  Req: Message + 'static,
  Resp: Message + 'static,
{
  fn register(
    &mut self,
    registry: &mio1::Registry,
    token: mio1::Token,
    interests: mio1::Interest,
  ) -> io::Result<()> {
    mio1::event::Source::register(&mut self.request_receiver, registry, token, interests)
  }

  fn reregister(
    &mut self,
    registry: &mio1::Registry,
    token: mio1::Token,
    interests: mio1::Interest,
  ) -> io::Result<()> {
    mio1::event::Source::reregister(&mut self.request_receiver, registry, token, interests)
  }

  fn deregister(&mut self, registry: &mio1::Registry) -> io::Result<()> {
    mio1::event::Source::deregister(&mut self.request_receiver, registry)
  }
}
