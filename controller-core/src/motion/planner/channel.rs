//! The two one-way channels between the planner (lower-priority task) and the executor
//! (control interrupt): spans and steps go from planner to executor. On the board they are
//! `heapless::spsc` queues (lock-free, the interrupt never waits); on the host a
//! `heapless::Deque` owned by [`super::MotionPlanner`].

use heapless::spsc::{Consumer, Producer};
use heapless::Deque;

/// Sending end of a bounded channel.
pub trait Sink<T> {
    /// Enqueues `item`, or gives it back when full.
    fn try_send(&mut self, item: T) -> Result<(), T>;
    /// Free places left.
    fn free(&self) -> usize;
}

/// Receiving end of a bounded channel.
pub trait Source<T> {
    fn try_recv(&mut self) -> Option<T>;
    /// The oldest item, left in the channel (the executor samples its current span in
    /// place: no copy per period).
    fn peek(&self) -> Option<&T>;
    /// Drops the oldest item.
    fn drop_front(&mut self) {
        let _ = self.try_recv();
    }
    /// Items waiting.
    fn waiting(&self) -> usize;
}

impl<T, const N: usize> Sink<T> for Deque<T, N> {
    fn try_send(&mut self, item: T) -> Result<(), T> {
        self.push_back(item)
    }
    fn free(&self) -> usize {
        N - self.len()
    }
}

impl<T, const N: usize> Source<T> for Deque<T, N> {
    fn try_recv(&mut self) -> Option<T> {
        self.pop_front()
    }
    fn peek(&self) -> Option<&T> {
        self.front()
    }
    fn waiting(&self) -> usize {
        self.len()
    }
}

impl<T> Sink<T> for Producer<'_, T> {
    fn try_send(&mut self, item: T) -> Result<(), T> {
        self.enqueue(item)
    }
    fn free(&self) -> usize {
        self.capacity() - self.len()
    }
}

impl<T> Source<T> for Consumer<'_, T> {
    fn try_recv(&mut self) -> Option<T> {
        self.dequeue()
    }
    fn peek(&self) -> Option<&T> {
        Consumer::peek(self)
    }
    fn waiting(&self) -> usize {
        self.len()
    }
}
