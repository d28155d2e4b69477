//! `/diagnostics` at 1 Hz, and the memory a burst left behind given back.

use std::time::{Duration, Instant};

use log::debug;

use super::{Shared, Wire};

/// Free heap below which the node gives nothing back to the OS (bytes). Memory given
/// back costs a page fault per 4 kB page when it is used again. Before rustdds was
/// patched to release samples within its KEEP_LAST depths, a steady stream
/// of scans kept a few MB in flight in its caches (about 10 MB at 100 scans a second);
/// trimming that every 5 s, as the node did, had the scans after each trim fault the
/// released pages in again (+12.6..+14.1 % instead of +7.3..+8.2 % over the bare relay
/// in 3000-round runs of `scripts/bench_latency.sh`). With the caches bounded by their
/// depths the heap stays well under this at any scan rate; the trim is a backstop.
const KEEP_FREE_HEAP: usize = 32 << 20;

/// After a burst, give memory the allocator holds but no longer uses back to the OS.
/// The DDS caches hold at most their QoS depths (and the samples a reliable reader has
/// not acknowledged yet; `vendor/rustdds/PATCHES.md`), so a full-speed burst of normal
/// scans leaves little free heap behind; a few huge messages (a 10^6-sample scan is
/// 8 MB) can, and glibc would keep that resident for good. Up to [`KEEP_FREE_HEAP`] of
/// free heap is kept: that memory is what the next scans will use.
fn release_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallinfo2 only reads the allocator's statistics and malloc_trim only
    // releases free heap memory; neither takes pointers.
    unsafe {
        if libc::mallinfo2().fordblks > KEEP_FREE_HEAP {
            libc::malloc_trim(0);
        }
    }
}

/// How long the node waits for a first `/clock` under `use_sim_time` before /diagnostics
/// warns that its time stands at 0.
const CLOCK_PATIENCE: Duration = Duration::from_secs(3);

/// Every second the cell's diagnostics published; every 5 s the freed memory released.
/// Never ends.
pub(super) async fn run(e: &impl Wire, shared: &Shared) {
    let mut tick = 0u64;
    // Since when the node has been on simulated time with no /clock.
    let mut clock_silent_since: Option<Instant> = None;
    loop {
        let now = shared.now();
        let waiting = e.use_sim_time() && now.ros.to_nanos() == 0;
        let silent_since = if waiting { *clock_silent_since.get_or_insert_with(Instant::now) } else { Instant::now() };
        clock_silent_since = waiting.then_some(silent_since);
        let clock_problem = match silent_since.elapsed() {
            silent if waiting && silent >= CLOCK_PATIENCE => format!(
                "use_sim_time is true and no /clock (rosgraph_msgs/msg/Clock) has come for {:.0} s: the node's time stands at 0",
                silent.as_secs_f64()
            ),
            _ => String::new(),
        };
        let publishers = e.raw_scan_publishers();
        let msg = {
            let mut st = shared.state.lock().expect("state lock");
            let received = st.stats.scans_received;
            st.driver.tick(Instant::now(), publishers, received);
            st.clock_problem = clock_problem;
            st.stats.peers_refused_authentication = crate::rmw::security::peers_refused_authentication();
            st.diagnostics(now)
        };
        if let Err(err) = e.publish_diagnostics(msg).await {
            debug!("cannot publish diagnostics: {err}");
        }
        tick += 1;
        if tick.is_multiple_of(5) {
            release_freed_memory();
        }
        smol::Timer::after(Duration::from_secs(1)).await;
    }
}
