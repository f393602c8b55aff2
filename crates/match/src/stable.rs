//! Stable matching of entries and exits (Ramirez et al. Algorithm 1, after Gusfield and Irving).
//!
//! Both sides rank each other by one pair score (lower is better; an entry breaks ties by the
//! exit's index, an exit by the entry's). Both rankings are then restrictions of one total
//! order on pairs, (score, entry, exit), and such preferences have exactly one stable matching:
//! the least pair of the order is in every stable matching (otherwise it blocks), and so on
//! with its row and column struck out. [`gale_shapley`] builds it greedily in that order, which
//! is what Gale-Shapley's proposals arrive at (the test below runs the textbook algorithm and
//! compares), in about 2 n^2 comparisons instead of proposals that sort refused entries' lists.

/// Matches `n` entries with `n` exits given `score[i * n + o]` (never negative). Returns the
/// exit of every entry: the unique stable matching (see the module comment).
pub fn gale_shapley(n: usize, score: &[f64]) -> Vec<usize> {
    debug_assert_eq!(score.len(), n * n);
    debug_assert!(score.iter().all(|s| s.is_finite() && *s >= 0.0));
    // Free entries and exits, each in increasing order, so that a strict `<` while scanning
    // keeps the lower index on a tie.
    let mut rows: Vec<usize> = (0..n).collect();
    let mut cols: Vec<usize> = (0..n).collect();
    let row_best = |i: usize, cols: &[usize]| -> usize {
        let row = &score[i * n..(i + 1) * n];
        let mut best = cols[0];
        for &o in &cols[1..] {
            if row[o] < row[best] {
                best = o;
            }
        }
        best
    };
    // Each free entry's best free exit. (Keeping a few best per row, to rescan less, was
    // slower: rows of real patches fall towards their best exit, so most exits insert.)
    let mut best: Vec<usize> = (0..n).map(|i| row_best(i, &cols)).collect();
    let mut exit_of = vec![usize::MAX; n];
    while !rows.is_empty() {
        // The least free pair of the order (score, entry, exit): the least of the rows' bests.
        let mut at = 0;
        for (k, &i) in rows.iter().enumerate().skip(1) {
            let j = rows[at];
            if score[i * n + best[i]] < score[j * n + best[j]] {
                at = k;
            }
        }
        let i = rows.remove(at);
        let o = best[i];
        exit_of[i] = o;
        cols.retain(|&c| c != o);
        for &j in &rows {
            if best[j] == o {
                best[j] = row_best(j, &cols);
            }
        }
    }
    exit_of
}

/// A pair (entry, exit) that would both rather be together than with their partners, if any.
pub fn blocking_pair(n: usize, score: &[f64], exit_of: &[usize]) -> Option<(usize, usize)> {
    let mut entry_of = vec![0usize; n];
    for (i, &o) in exit_of.iter().enumerate() {
        entry_of[o] = i;
    }
    (0..n)
        .flat_map(|i| (0..n).map(move |o| (i, o)))
        .find(|&(i, o)| {
            let s = score[i * n + o];
            exit_of[i] != o && s < score[i * n + exit_of[i]] && s < score[entry_of[o] * n + o]
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Textbook Gale-Shapley, entries proposing down their sorted lists.
    fn proposals(n: usize, score: &[f64]) -> Vec<usize> {
        let lists: Vec<Vec<usize>> = (0..n)
            .map(|i| {
                let mut l: Vec<usize> = (0..n).collect();
                l.sort_by(|&a, &b| {
                    score[i * n + a]
                        .total_cmp(&score[i * n + b])
                        .then(a.cmp(&b))
                });
                l
            })
            .collect();
        let prefers = |o: usize, i: usize, j: usize| {
            let (si, sj) = (score[i * n + o], score[j * n + o]);
            si < sj || (si == sj && i < j)
        };
        let mut next = vec![0usize; n];
        let mut partner: Vec<Option<usize>> = vec![None; n];
        let mut free: Vec<usize> = (0..n).rev().collect();
        while let Some(i) = free.pop() {
            let o = lists[i][next[i]];
            next[i] += 1;
            match partner[o] {
                None => partner[o] = Some(i),
                Some(j) if prefers(o, i, j) => {
                    partner[o] = Some(i);
                    free.push(j);
                }
                Some(_) => free.push(i),
            }
        }
        let mut exit_of = vec![0; n];
        for (o, i) in partner.iter().enumerate() {
            exit_of[i.unwrap()] = o;
        }
        exit_of
    }

    fn scores(n: usize, seed: u64, levels: u64) -> Vec<f64> {
        let mut x = seed | 1;
        (0..n * n)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                (x % levels) as f64 / 100.0
            })
            .collect()
    }

    proptest! {
        /// Every entry and exit is matched exactly once, and no blocking pair remains.
        #[test]
        fn matching_is_perfect_and_stable(n in 1usize..40, seed in any::<u64>()) {
            let score = scores(n, seed, 1000);
            let exit_of = gale_shapley(n, &score);
            let mut seen = vec![false; n];
            for &o in &exit_of {
                prop_assert!(!seen[o], "exit {o} matched twice");
                seen[o] = true;
            }
            prop_assert_eq!(blocking_pair(n, &score, &exit_of), None);
        }

        /// The greedy order gives what Gale-Shapley's proposals give, ties included (few score
        /// levels make many).
        #[test]
        fn the_same_matching_as_proposals(n in 1usize..50, seed in any::<u64>(), levels in 2u64..1000) {
            let score = scores(n, seed, levels);
            prop_assert_eq!(gale_shapley(n, &score), proposals(n, &score));
        }
    }

    #[test]
    fn everyone_gets_their_first_choice_when_choices_differ() {
        let score = [0.0, 1.0, 1.0, 0.0];
        assert_eq!(gale_shapley(2, &score), vec![0, 1]);
    }
}
