//! Rays traced, by kind: what every bake, view and reference counts.

/// Rays traced, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayCounts {
    /// Sampling rays (Kontkanen & Laine 2006 Algorithm 2; point-sampling directions).
    pub sampling: u64,
    /// Query rays towards back-face points (Algorithm 2) and point-classifier rays.
    pub query: u64,
    /// Path continuation rays after a diffuse bounce.
    pub bounce: u64,
    /// Shadow rays of next-event estimation.
    pub shadow: u64,
}

impl RayCounts {
    /// Sum over all kinds.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.sampling + self.query + self.bounce + self.shadow
    }

    /// Adds another count.
    pub fn add(&mut self, o: &Self) {
        self.sampling += o.sampling;
        self.query += o.query;
        self.bounce += o.bounce;
        self.shadow += o.shadow;
    }
}

/// Reports show the four kinds and their [`RayCounts::total`]:
/// `{"sampling", "query", "bounce", "shadow", "total"}`.
impl serde::Serialize for RayCounts {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut st = s.serialize_struct("RayCounts", 5)?;
        st.serialize_field("sampling", &self.sampling)?;
        st.serialize_field("query", &self.query)?;
        st.serialize_field("bounce", &self.bounce)?;
        st.serialize_field("shadow", &self.shadow)?;
        st.serialize_field("total", &self.total())?;
        st.end()
    }
}
