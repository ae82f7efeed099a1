//! What a `--fill TARGET=scene.NAME` source names ([`Item`]), apart from `scene_data` (which
//! lays the data out) so that `fill` can parse it without depending on the layouts.
use serde::{Deserialize, Serialize};

/// What a `scene.NAME` fill source names.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Item {
    Positions,
    Normals,
    Uvs,
    Indices,
    Materials,
    PrimInfo,
    SceneDesc,
    Textures,
}

/// The buffers `scene_desc` holds the addresses of, in its order.
pub const DESC_ORDER: [Item; 6] =
    [Item::Positions, Item::Normals, Item::Uvs, Item::Indices, Item::Materials, Item::PrimInfo];

/// Every item, for errors and help.
pub const ALL: [Item; 8] = [
    Item::Positions,
    Item::Indices,
    Item::Normals,
    Item::Uvs,
    Item::Materials,
    Item::PrimInfo,
    Item::SceneDesc,
    Item::Textures,
];

impl Item {
    pub fn name(self) -> &'static str {
        match self {
            Item::Positions => "positions",
            Item::Normals => "normals",
            Item::Uvs => "uvs",
            Item::Indices => "indices",
            Item::Materials => "materials",
            Item::PrimInfo => "prim_info",
            Item::SceneDesc => "scene_desc",
            Item::Textures => "textures",
        }
    }

    /// `NAME` of `scene.NAME`.
    pub fn parse(name: &str) -> Option<Item> {
        ALL.into_iter().find(|i| i.name() == name)
    }
}
