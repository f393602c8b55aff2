//! Gale-Shapley stable matching (Ramirez et al. Algorithm 1, after Gusfield and Irving).

/// Matches `n` entries with `n` exits given `score[i * n + o]` (lower is better for both
/// sides: entries and exits rank each other by the same pair score, ties broken by index).
/// Entries propose. Returns the exit of every entry.
pub fn gale_shapley(n: usize, score: &[f64]) -> Vec<usize> {
    debug_assert_eq!(score.len(), n * n);
    // Scores are never negative, so their bits order like the numbers: a pair's place in a
    // proposal list is a plain integer, the exit's index breaking ties.
    debug_assert!(score.iter().all(|&s| s >= 0.0));
    let key = |i: usize, o: usize| ((score[i * n + o].to_bits() as u128) << 32) | o as u128;
    // Most entries propose once or twice: those proposals scan the row for the next key, and
    // only an entry refused more often sorts its whole list.
    const SCANNED: usize = 3;
    let mut last = vec![0u128; n];
    let mut made = vec![0usize; n];
    let mut sorted: Vec<Vec<u128>> = vec![Vec::new(); n];
    let mut partner_of_exit: Vec<Option<usize>> = vec![None; n];
    let mut free: std::collections::VecDeque<usize> = (0..n).collect();
    let prefers = |o: usize, i: usize, j: usize| {
        // Does exit `o` prefer entry `i` to entry `j`?
        let (si, sj) = (score[i * n + o], score[j * n + o]);
        si < sj || (si == sj && i < j)
    };
    while let Some(i) = free.pop_front() {
        let k = made[i];
        let next = if k < SCANNED {
            (0..n)
                .map(|o| key(i, o))
                .filter(|&x| k == 0 || x > last[i])
                .min()
        } else {
            if sorted[i].is_empty() {
                sorted[i] = (0..n).map(|o| key(i, o)).collect();
                sorted[i].sort_unstable();
            }
            sorted[i].get(k).copied()
        };
        let next = next.expect("an entry is free only while some exit has not refused it");
        last[i] = next;
        made[i] += 1;
        let o = (next & 0xffff_ffff) as usize;
        match partner_of_exit[o] {
            None => partner_of_exit[o] = Some(i),
            Some(j) if prefers(o, i, j) => {
                partner_of_exit[o] = Some(i);
                free.push_back(j);
            }
            Some(_) => free.push_back(i),
        }
    }
    let mut exit_of = vec![0usize; n];
    for (o, i) in partner_of_exit.iter().enumerate() {
        exit_of[i.expect("every exit is taken when lists are complete")] = o;
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

    proptest! {
        /// Every entry and exit is matched exactly once, and no blocking pair remains.
        #[test]
        fn matching_is_perfect_and_stable(n in 1usize..40, seed in any::<u64>()) {
            let mut x = seed | 1;
            let score: Vec<f64> = (0..n * n)
                .map(|_| {
                    x ^= x << 13;
                    x ^= x >> 7;
                    x ^= x << 17;
                    (x % 1000) as f64 / 100.0
                })
                .collect();
            let exit_of = gale_shapley(n, &score);
            let mut seen = vec![false; n];
            for &o in &exit_of {
                prop_assert!(!seen[o], "exit {o} matched twice");
                seen[o] = true;
            }
            prop_assert_eq!(blocking_pair(n, &score, &exit_of), None);
        }
    }

    #[test]
    fn everyone_gets_their_first_choice_when_choices_differ() {
        let score = [0.0, 1.0, 1.0, 0.0];
        assert_eq!(gale_shapley(2, &score), vec![0, 1]);
    }
}
