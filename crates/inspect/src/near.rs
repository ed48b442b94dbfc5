//! "Did you mean": the names near a misspelt one, for every message that refuses a name (a
//! register on the command line, a model, key, line or register in a bus file).

/// Most names a "did you mean" lists.
const MOST_NEAR: usize = 5;

/// The names among `known` near `name`, nearest first, at most five: a typo of up to a third
/// of its letters (at least one edit: Damerau-Levenshtein, so a swap of two letters is one),
/// or a name that contains it or is contained in it (`fast`: `fastest`). Case is ignored.
pub fn near<'a>(name: &str, known: impl IntoIterator<Item = &'a str>) -> Vec<&'a str> {
    let wanted = name.to_lowercase();
    if wanted.is_empty() {
        return Vec::new();
    }
    let most_edits = (wanted.chars().count() / 3).max(1);
    let mut found: Vec<(usize, &'a str)> = known
        .into_iter()
        .filter_map(|candidate| {
            let lower = candidate.to_lowercase();
            let edits = strsim::damerau_levenshtein(&wanted, &lower);
            let near = edits <= most_edits || lower.contains(&wanted) || wanted.contains(&lower);
            (near && !lower.is_empty()).then_some((edits, candidate))
        })
        .collect();
    found.sort_unstable();
    found.dedup();
    found.truncate(MOST_NEAR);
    found.into_iter().map(|(_, candidate)| candidate).collect()
}

/// `did you mean `a`, `b`?` for the names [`near`] finds, or `None` when none is near.
pub fn did_you_mean<'a>(name: &str, known: impl IntoIterator<Item = &'a str>) -> Option<String> {
    // A name that is known as written is refused for another reason: no typo to point at.
    let mut found = near(name, known);
    found.retain(|candidate| *candidate != name);
    (!found.is_empty()).then(|| {
        let names: Vec<String> = found.iter().map(|n| format!("`{n}`")).collect();
        format!("did you mean {}?", names.join(", "))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn typos_swaps_and_parts_are_near_and_others_are_not() {
        let known = ["distance_1", "distance_2", "light_power", "fastest"];
        assert_eq!(near("distanse_1", known), ["distance_1", "distance_2"]);
        assert_eq!(near("ligth_power", known), ["light_power"]);
        assert_eq!(near("fast", known), ["fastest"]);
        assert_eq!(near("FASTEST", known), ["fastest"]);
        assert!(near("temperature", known).is_empty());
        assert!(near("", known).is_empty());
        // Found in the README walk: `slave_address` refused under `writable` was told "did
        // you mean `slave_address`?".
        assert_eq!(did_you_mean("light_power", known), None);
        assert_eq!(
            did_you_mean("Light_Power", known).as_deref(),
            Some("did you mean `light_power`?")
        );
        assert_eq!(
            did_you_mean("timout", ["timeout", "retries"]).as_deref(),
            Some("did you mean `timeout`?")
        );
        assert_eq!(did_you_mean("zzz", ["timeout"]), None);
    }
}
