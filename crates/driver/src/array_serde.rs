//! Arrays of any length as sequences (serde's own impls stop at 32 elements): the copies of
//! a repeat member in a generated group, e.g. a buffer page's 60 samples. For
//! `#[serde(with = "optobus_driver::array_serde")]`.

use std::fmt;
use std::marker::PhantomData;

use serde::de::{Error as _, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// The elements in order.
pub fn serialize<T: Serialize, const N: usize, S: Serializer>(
    array: &[T; N],
    serializer: S,
) -> Result<S::Ok, S::Error> {
    serializer.collect_seq(array)
}

/// Exactly `N` elements: fewer or more is refused, never padded or cut.
pub fn deserialize<'de, T: Deserialize<'de>, const N: usize, D: Deserializer<'de>>(
    deserializer: D,
) -> Result<[T; N], D::Error> {
    struct Elements<T, const N: usize>(PhantomData<T>);

    impl<'de, T: Deserialize<'de>, const N: usize> Visitor<'de> for Elements<T, N> {
        type Value = [T; N];

        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            write!(f, "a sequence of {N} elements")
        }

        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<[T; N], A::Error> {
            let mut elements = Vec::with_capacity(N);
            while let Some(element) = seq.next_element()? {
                if elements.len() == N {
                    return Err(A::Error::invalid_length(N + 1, &self));
                }
                elements.push(element);
            }
            let found = elements.len();
            elements
                .try_into()
                .map_err(|_| A::Error::invalid_length(found, &self))
        }
    }

    deserializer.deserialize_seq(Elements(PhantomData))
}

#[cfg(test)]
mod tests {
    #[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
    struct Page {
        #[serde(with = "super")]
        samples: [u16; 40],
    }

    #[test]
    fn long_arrays_round_trip_and_wrong_lengths_are_refused() {
        let page = Page {
            samples: std::array::from_fn(|i| i as u16 * 3),
        };
        let json = serde_json::to_string(&page).unwrap();
        assert!(json.starts_with(r#"{"samples":[0,3,6,"#), "{json}");
        assert_eq!(serde_json::from_str::<Page>(&json).unwrap(), page);
        let short = r#"{"samples":[1,2,3]}"#;
        let error = serde_json::from_str::<Page>(short).unwrap_err().to_string();
        assert!(
            error.contains("invalid length 3, expected a sequence of 40"),
            "{error}"
        );
        let long = format!(r#"{{"samples":[{}]}}"#, vec!["1"; 41].join(","));
        assert!(serde_json::from_str::<Page>(&long).is_err());
    }
}
