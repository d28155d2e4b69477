//! `~/get_type_description` (REP-2016): the description of each type the node's endpoints
//! use, with its sources when asked, as rcl answers it
//! ([`crate::interfaces::type_description`]).

use futures::StreamExt;
use log::{debug, warn};

use super::Wire;
use crate::interfaces::type_description::answer;

/// Each request answered in turn. Ends when the server's request stream does.
pub(super) async fn run(e: &impl Wire) {
    let mut requests = std::pin::pin!(e.type_description_requests());
    while let Some(item) = requests.next().await {
        let (id, req) = match item {
            Ok(r) => r,
            Err(err) => {
                warn!("cannot read a type description request: {err}");
                continue;
            }
        };
        let types = e.types_in_use();
        let response = answer(&req, types.iter().map(String::as_str));
        debug!(
            "type description of {} ({}): {}",
            req.type_name,
            req.type_hash,
            if response.successful { "sent" } else { &response.failure_reason }
        );
        if let Err(err) = e.answer_type_description(id, response).await {
            warn!("cannot send a type description response: {err}");
        }
    }
}
