//! The tag → track map: each track's index in a hash table keyed by its tag's hash, the tag
//! itself compared in the track.
//!
//! A record's tag is hashed and looked up; on a site of 100 000 tags the table's entry is a
//! cache miss per record. A map of `Arc<str>` keys (24-byte entries, 3 MB at 100 000 tags)
//! then loaded each candidate key's text from its own allocation — a second miss; entries of
//! a 4-byte index keep the table at 0.5 MB, which stays in the L2 cache more often, and the
//! tag compared is the track's, whose record is about to be applied anyway.

use std::collections::hash_map::RandomState;
use std::hash::BuildHasher;

use hashbrown::HashTable;

use super::track::Track;

/// The index of each tag's track in the tracker's track list (see the
/// [module documentation](self)).
#[derive(Debug, Clone, Default)]
pub(super) struct TagIndex {
    table: HashTable<u32>,
    hasher: RandomState,
}

impl TagIndex {
    fn hash(&self, tag: &str) -> u64 {
        self.hasher.hash_one(tag)
    }

    /// The index of `tag`'s track in `tracks`.
    pub(super) fn get<const N: usize>(&self, tag: &str, tracks: &[Track<N>]) -> Option<usize> {
        self.table
            .find(self.hash(tag), |&i| *tracks[i as usize].tag == *tag)
            .map(|&i| i as usize)
    }

    /// Adds `tracks`' last track (a new tag's), so `tracks.len() − 1` is its index.
    ///
    /// # Panics
    /// Beyond 2³² tracks.
    pub(super) fn push<const N: usize>(&mut self, tracks: &[Track<N>]) {
        let index = tracks.len() - 1;
        let hash = self.hash(&tracks[index].tag);
        let index = u32::try_from(index).expect("fewer than 2³² tracks");
        self.table
            .insert_unique(hash, index, |&i| self.hasher.hash_one(&*tracks[i as usize].tag));
    }

    /// The index of `tracks`, whose tags are distinct (those of a tracker's tracks).
    pub(super) fn of_distinct<const N: usize>(tracks: &[Track<N>]) -> Self {
        let mut index = Self {
            table: HashTable::with_capacity(tracks.len()),
            hasher: RandomState::new(),
        };
        for i in 0..tracks.len() {
            index.push(&tracks[..=i]);
        }
        index
    }

    /// The index of `tracks`, anew; `Err` with a tag that appears twice.
    pub(super) fn of<const N: usize>(tracks: &[Track<N>]) -> Result<Self, String> {
        let mut index = Self {
            table: HashTable::with_capacity(tracks.len()),
            hasher: RandomState::new(),
        };
        for (i, track) in tracks.iter().enumerate() {
            if index.get(&track.tag, &tracks[..i]).is_some() {
                return Err(track.tag.to_string());
            }
            index.push(&tracks[..=i]);
        }
        Ok(index)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;

    #[test]
    fn tags_are_found_at_their_track_and_duplicates_named() {
        let tags = ["tag-000123", "", "a-tag-id-longer-than-twenty-two-bytes", "tag-000124"];
        let tracks: Vec<Track<4>> = tags.iter().map(|&tag| Track::new(Arc::from(tag), 0, 0)).collect();
        let mut grown = TagIndex::default();
        for i in 0..tracks.len() {
            grown.push(&tracks[..=i]);
        }
        for index in [grown, TagIndex::of(&tracks).unwrap(), TagIndex::of_distinct(&tracks)] {
            for (i, tag) in tags.iter().enumerate() {
                assert_eq!(index.get(tag, &tracks), Some(i));
            }
            assert_eq!(index.get("tag-00012", &tracks), None);
        }
        let twice: Vec<Track<4>> = ["a", "b", "a"]
            .iter()
            .map(|&tag| Track::new(Arc::from(tag), 0, 0))
            .collect();
        assert_eq!(TagIndex::of(&twice).unwrap_err(), "a");
    }
}
