//! A fixed-size min segment tree over `S` slots (`S` a power of two): point update, range
//! minimum and "first slot below x" in O(log S), no allocation. The span ring keeps one
//! for the speed caps and one for the acceleration limits, indexed by the span's sequence
//! number modulo `S` (continuous across the u32 wrap since `S` divides 2³²).

/// Node `i` of the implicit tree: 1..S internal (`node`), S..2S leaves (`leaf`).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct MinTree<const S: usize> {
    node: [f32; S],
    leaf: [f32; S],
}

/// Right-hand nodes of a range cover kept at most (one per level: S ≤ 2²⁴).
const MAX_DEPTH: usize = 24;

impl<const S: usize> MinTree<S> {
    const POW2: () = assert!(
        S.is_power_of_two() && S >= 2 && S <= 1 << MAX_DEPTH,
        "the span capacity must be a power of two (≥ 2)"
    );

    pub const fn new() -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::POW2;
        Self {
            node: [f32::INFINITY; S],
            leaf: [f32::INFINITY; S],
        }
    }

    #[inline(always)]
    fn val(&self, i: usize) -> f32 {
        if i >= S {
            self.leaf.get(i - S).copied().unwrap_or(f32::INFINITY)
        } else {
            self.node.get(i).copied().unwrap_or(f32::INFINITY)
        }
    }

    #[inline(always)]
    fn pull(&mut self, i: usize) {
        let (l, r) = (self.val(2 * i), self.val(2 * i + 1));
        if let Some(n) = self.node.get_mut(i) {
            *n = if l < r { l } else { r };
        }
    }

    /// Sets slot `p` (taken modulo `S`).
    pub fn set(&mut self, p: usize, x: f32) {
        let p = p & (S - 1);
        if let Some(l) = self.leaf.get_mut(p) {
            *l = x;
        }
        let mut i = (p + S) >> 1;
        while i >= 1 {
            self.pull(i);
            i >>= 1;
        }
    }

    /// Sets slot `p` without updating the internal nodes (call [`MinTree::rebuild`]).
    pub fn set_raw(&mut self, p: usize, x: f32) {
        if let Some(l) = self.leaf.get_mut(p & (S - 1)) {
            *l = x;
        }
    }

    pub fn rebuild(&mut self) {
        for i in (1..S).rev() {
            self.pull(i);
        }
    }

    /// Minimum over the physical slots `l..=r` (`l ≤ r < S`).
    fn min_phys(&self, l: usize, r: usize) -> f32 {
        let (mut lo, mut hi) = (l + S, r + S + 1);
        let mut m = f32::INFINITY;
        while lo < hi {
            if lo & 1 == 1 {
                let v = self.val(lo);
                if v < m {
                    m = v;
                }
                lo += 1;
            }
            if hi & 1 == 1 {
                hi -= 1;
                let v = self.val(hi);
                if v < m {
                    m = v;
                }
            }
            lo >>= 1;
            hi >>= 1;
        }
        m
    }

    /// Minimum over the `n ≥ 1` consecutive slots from `p` (modulo `S`, wrapping).
    pub fn min_run(&self, p: usize, n: usize) -> f32 {
        if n == 0 {
            return f32::INFINITY;
        }
        let n = n.min(S);
        let l = p & (S - 1);
        let r = l + n - 1;
        if r < S {
            self.min_phys(l, r)
        } else {
            let a = self.min_phys(l, S - 1);
            let b = self.min_phys(0, r - S);
            if a < b {
                a
            } else {
                b
            }
        }
    }

    /// Descends from node `i` (whose value is below `x`) to its first leaf below `x`.
    #[inline]
    fn descend(&self, mut i: usize, x: f32) -> usize {
        while i < S {
            i = if self.val(2 * i) < x {
                2 * i
            } else {
                2 * i + 1
            };
        }
        i - S
    }

    /// First physical slot in `l..=r` with a value below `x`: the canonical cover of the
    /// range, left nodes in order as they come, right nodes afterwards in reverse.
    fn first_below_phys(&self, l: usize, r: usize, x: f32) -> Option<usize> {
        let mut right = [0u32; MAX_DEPTH];
        let mut nr = 0;
        let (mut lo, mut hi) = (l + S, r + S + 1);
        while lo < hi {
            if lo & 1 == 1 {
                if self.val(lo) < x {
                    return Some(self.descend(lo, x));
                }
                lo += 1;
            }
            if hi & 1 == 1 {
                hi -= 1;
                if let Some(s) = right.get_mut(nr) {
                    *s = hi as u32;
                    nr += 1;
                }
            }
            lo >>= 1;
            hi >>= 1;
        }
        for &i in right.iter().take(nr).rev() {
            if self.val(i as usize) < x {
                return Some(self.descend(i as usize, x));
            }
        }
        None
    }

    /// Offset (0..n) of the first of the `n` consecutive slots from `p` (wrapping) with a
    /// value below `x`.
    pub fn first_below_run(&self, p: usize, n: usize, x: f32) -> Option<usize> {
        if n == 0 {
            return None;
        }
        let n = n.min(S);
        let l = p & (S - 1);
        let r = l + n - 1;
        if r < S {
            self.first_below_phys(l, r, x).map(|q| q - l)
        } else {
            self.first_below_phys(l, S - 1, x)
                .map(|q| q - l)
                .or_else(|| self.first_below_phys(0, r - S, x).map(|q| q + S - l))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn queries_match_brute_force_with_wrap() {
        const S: usize = 16;
        let mut t: MinTree<S> = MinTree::new();
        let mut vals = [f32::INFINITY; S];
        let mut x = 987654321u32;
        let mut rnd = move || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x
        };
        for _ in 0..2000 {
            let p = (rnd() as usize) % S;
            let v = (rnd() % 50) as f32;
            t.set(p, v);
            vals[p] = v;
            let start = (rnd() as usize) % S;
            let n = 1 + (rnd() as usize) % S;
            let idx = |k: usize| (start + k) % S;
            let want = (0..n).map(|k| vals[idx(k)]).fold(f32::INFINITY, f32::min);
            assert_eq!(t.min_run(start, n), want);
            let thr = (rnd() % 50) as f32;
            let want_first = (0..n).find(|&k| vals[idx(k)] < thr);
            assert_eq!(t.first_below_run(start, n, thr), want_first);
        }
        let mut u: MinTree<S> = MinTree::new();
        for (p, v) in vals.iter().enumerate() {
            u.set_raw(p, *v);
        }
        u.rebuild();
        assert_eq!(u, t);
    }
}
