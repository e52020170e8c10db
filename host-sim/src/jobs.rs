//! One parallel runner for every study: runs independent jobs on all cores (the build
//! machine has two) and returns their results in job order; the first error wins.

use anyhow::{anyhow, Result};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// Threads used: the machine's available parallelism (at least one).
pub fn threads() -> usize {
    std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
}

/// Run `f` on every job, in parallel, returning the results in job order.
pub fn run_all<J: Sync, T: Send>(jobs: &[J], f: impl Fn(&J) -> Result<T> + Sync) -> Result<Vec<T>> {
    let next = AtomicUsize::new(0);
    let slots: Vec<Mutex<Option<Result<T>>>> = jobs.iter().map(|_| Mutex::new(None)).collect();
    let workers = threads().min(jobs.len()).max(1);
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(job) = jobs.get(i) else { break };
                let r = f(job);
                if let Ok(mut slot) = slots[i].lock() {
                    *slot = Some(r);
                }
            });
        }
    });
    slots
        .into_iter()
        .map(|m| {
            m.into_inner()
                .map_err(|_| anyhow!("a simulation thread panicked"))?
                .unwrap_or_else(|| Err(anyhow!("a simulation thread panicked")))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_order_and_reports_the_first_error() {
        let jobs: Vec<u32> = (0..20).collect();
        let out = run_all(&jobs, |j| Ok(j * 2)).unwrap();
        assert_eq!(out, (0..20).map(|j| j * 2).collect::<Vec<_>>());
        let err = run_all(&jobs, |j| {
            if *j == 7 {
                Err(anyhow!("job 7 failed"))
            } else {
                Ok(*j)
            }
        });
        assert_eq!(err.unwrap_err().to_string(), "job 7 failed");
    }
}
