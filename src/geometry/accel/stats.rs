//! Traversal counters, compiled in only with the cargo feature
//! `trav-stats` (else `count!` expands to nothing): per kind of query, the
//! rays, the inner nodes they visit, the child boxes tested (one per slab
//! lane: a packet's node tests each child against all its rays), the
//! leaves and the triangles tested (the lanes of the leaf's packet that
//! hold triangles). Printed to stderr, with the tree's SAH cost, when the
//! top-level BVH is dropped. For measurements only.
#![cfg_attr(not(feature = "trav-stats"), allow(dead_code))]

#[cfg(feature = "trav-stats")]
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

/// The kinds of query.
pub const CLOSEST: usize = 0;
pub const CLOSEST_PACKET: usize = 1;
pub const OCCLUDED: usize = 2;
pub const OCCLUDED_PACKET: usize = 3;
const KINDS: [&str; 4] = ["closest (single ray)", "closest (packets)", "occluded (single ray)", "occluded (packets)"];

/// The counters of a kind.
pub const RAYS: usize = 0;
pub const NODES: usize = 1;
pub const BOXES: usize = 2;
pub const LEAVES: usize = 3;
pub const TRIS: usize = 4;
/// Rays a packet handed to the single-ray traversal below some node.
pub const SPLIT_OFF: usize = 5;
const N: usize = 6;

#[cfg(feature = "trav-stats")]
static COUNTS: [[AtomicU64; N]; 4] = [const { [const { AtomicU64::new(0) }; N] }; 4];

#[cfg(feature = "trav-stats")]
#[inline(always)]
pub fn add(kind: usize, what: usize, n: u64) {
    COUNTS[kind][what].fetch_add(n, Relaxed);
}

/// Adds `n` to counter `what` of query kind `kind` (only with `trav-stats`).
macro_rules! count {
    ($kind:expr, $what:expr, $n:expr) => {
        #[cfg(feature = "trav-stats")]
        $crate::geometry::accel::stats::add($kind, $what, $n as u64);
    };
}
pub(crate) use count;

/// The counters per ray, and the reset; a no-op without `trav-stats`.
pub fn report(sah: f64, nodes: usize, leaves: usize) {
    #[cfg(feature = "trav-stats")]
    {
        eprintln!("BVH: {nodes} nodes, {leaves} leaves, SAH cost {sah:.2} (node 1, leaf packet 1)");
        for (k, name) in KINDS.iter().enumerate() {
            let c: Vec<u64> = COUNTS[k].iter().map(|a| a.swap(0, Relaxed)).collect();
            if c[RAYS] == 0 {
                continue;
            }
            let per = |x: u64| x as f64 / c[RAYS] as f64;
            eprintln!(
                "{name}: {} rays; per ray {:.2} nodes, {:.2} boxes, {:.2} leaves, {:.2} triangles; {:.3} split off to single rays",
                c[RAYS],
                per(c[NODES]),
                per(c[BOXES]),
                per(c[LEAVES]),
                per(c[TRIS]),
                per(c[SPLIT_OFF])
            );
        }
    }
    #[cfg(not(feature = "trav-stats"))]
    let _ = (sah, nodes, leaves);
}
