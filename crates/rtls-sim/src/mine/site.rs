//! The site file the tracker needs for a [`MineLayout`]: readers with their radio, the zones,
//! the tracker and alarm settings.

use std::fmt::Write as _;

use rtls_engine::zones::{Shape, Zone, ZoneKind};

use super::MineLayout;

/// What [`MineLayout::site_toml`] and [`MineLayout::zones`] write besides the layout itself.
///
/// # Examples
/// ```
/// use rtls_sim::mine::SiteOptions;
/// let options = SiteOptions { drift_zones: true, ..SiteOptions::default() };
/// assert!(options.name.is_none());
/// ```
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SiteOptions {
    /// The site's name; `None` uses the layout's [`MineLayout::name`].
    pub name: Option<String>,
    /// Also write one area-of-interest zone per drift (head counts per drift on the map).
    pub drift_zones: bool,
    /// Write neither the tunnels as `[[corridors]]` nor the readers' `sensitivity_dbm`: the
    /// tracker without seed 000's map and negative information (for comparisons).
    pub without_map: bool,
}

/// The tracker and alarm settings of the mine's site file: the tightly coupled EKF on raw
/// RSSI with a constant-velocity model, a 10 s coast timeout, one output per second, and
/// predictive hazard alarms over a 10 s horizon. With the tunnels as corridors and the readers'
/// sensitivity (unless [`SiteOptions::without_map`]), the map constraint and negative
/// information apply too.
const TRACKER_SETTINGS: &str = "\
[tracker]
pipeline = \"tightly-coupled\"
motion_model = \"cv\"
filter = \"ekf\"
acceleration_noise_std_mps2 = 0.3
gate_probability = 0.999
initiation = { confirm_updates = 3, within_s = 5.0 }
coast_timeout_s = 10.0
delete_timeout_s = 120.0
reorder_window_s = 0.0
rewind_horizon_s = 2.0
output_interval_s = 1.0

[alarms]
horizon_s = 10.0
step_s = 0.5
entry_probability = 0.5
";

impl MineLayout {
    /// The site file (TOML, as `rtls_engine::site::Site::from_toml_str` reads it) for this
    /// layout: every reader (technology `rfid`, its `working` flag, the radio's path loss), the
    /// zones of [`MineLayout::zones`] (the collapse as a hazard with alarms), and the tracker
    /// and alarm settings seed 000's mine is checked with (tightly coupled EKF, 10 s coast
    /// timeout, 1 s outputs, 10 s alarm horizon).
    ///
    /// # Examples
    /// ```
    /// use rtls_sim::mine::{MineLayout, SiteOptions};
    /// let text = MineLayout::seed000().site_toml(&SiteOptions::default());
    /// let site = rtls_engine::site::Site::from_toml_str(&text, "mine.toml").unwrap();
    /// assert_eq!(site.readers.len(), 307);
    /// assert_eq!(site.readers.iter().filter(|r| !r.working).count(), 1);
    /// assert_eq!(site.zones[0].id, "collapse");
    /// ```
    #[must_use]
    pub fn site_toml(&self, options: &SiteOptions) -> String {
        let name = options.name.as_deref().unwrap_or(&self.name);
        let radio = &self.radio;
        let mut text = format!("name = {}\n", toml_string(name));
        for reader in &self.readers {
            let [x, y] = reader.position_m;
            // writing into a String cannot fail
            let _ = write!(
                text,
                "\n[[readers]]\nid = {}\nposition_m = [{x:?}, {y:?}]\ntechnology = \"rfid\"\nworking = {}\n\
                 radio = {{ path_loss = {{ reference_power_dbm = {:?}, exponent = {:?}, shadowing_std_db = {:?}, \
                 reference_distance_m = 1.0 }}{} }}\n",
                toml_string(&reader.id),
                reader.working,
                radio.reference_power_dbm,
                radio.exponent,
                radio.shadowing_std_db,
                if options.without_map {
                    String::new()
                } else {
                    format!(", sensitivity_dbm = {:?}", radio.sensitivity_dbm)
                },
            );
        }
        if !options.without_map {
            for drift in &self.drifts {
                let [x0, x1] = drift.x_range_m;
                let _ = write!(
                    text,
                    "\n[[corridors]]\nid = {}\npoints_m = [[{x0:?}, {y:?}], [{x1:?}, {y:?}]]\nhalf_width_m = {:?}\n",
                    toml_string(&drift.name),
                    self.tunnel_half_width_m,
                    y = drift.y_m,
                );
            }
            let cut = &self.cross_cut;
            let [y0, y1] = cut.y_range_m;
            let _ = write!(
                text,
                "\n[[corridors]]\nid = {}\npoints_m = [[{x:?}, {y0:?}], [{x:?}, {y1:?}]]\nhalf_width_m = {:?}\n",
                toml_string(&cut.name),
                self.tunnel_half_width_m,
                x = cut.x_m,
            );
        }
        for zone in self.zones(options) {
            text.push('\n');
            write_zone(&mut text, &zone);
        }
        text.push('\n');
        text.push_str(TRACKER_SETTINGS);
        text
    }
}

/// Appends `zone` as a `[[zones]]` table.
fn write_zone(text: &mut String, zone: &Zone) {
    let kind = match zone.kind {
        ZoneKind::Hazard => "hazard",
        ZoneKind::Restricted => "restricted",
        ZoneKind::AreaOfInterest => "area-of-interest",
    };
    let readers: Vec<String> = zone.readers.iter().map(|r| toml_string(r)).collect();
    let shape = match &zone.shape {
        Shape::Polygon {
            vertices_m,
            floor,
            z_range_m,
        } => {
            let vertices: Vec<String> = vertices_m.iter().map(|[x, y]| format!("[{x:?}, {y:?}]")).collect();
            let mut shape = format!("{{ type = \"polygon\", vertices_m = [{}]", vertices.join(", "));
            if let Some(floor) = floor {
                let _ = write!(shape, ", floor = {}", toml_string(floor));
            }
            if let Some([z0, z1]) = z_range_m {
                let _ = write!(shape, ", z_range_m = [{z0:?}, {z1:?}]");
            }
            shape + " }"
        }
        Shape::Box { min_m, max_m } => format!("{{ type = \"box\", min_m = {min_m:?}, max_m = {max_m:?} }}"),
    };
    let _ = write!(
        text,
        "[[zones]]\nid = {}\nname = {}\nkind = \"{kind}\"\nreaders = [{}]\nshape = {shape}\n",
        toml_string(&zone.id),
        toml_string(&zone.name),
        readers.join(", "),
    );
}

/// `value` as a TOML basic string, quoted and escaped.
fn toml_string(value: &str) -> String {
    toml::Value::String(value.to_owned()).to_string()
}
