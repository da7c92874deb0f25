// The `sensors` component (MjcfSensors): a robot's MJCF <sensor> elements, read by name.
#include <algorithm>
#include <cmath>

#include "simgate/core/errors.h"
#include "simgate/sim/actuator_kind.h"
#include "simgate/sim/actuators_sensors.h"

namespace simgate::sim {

namespace {
// The sensorised object's MJCF kind as the <sensor objtype> attribute spells it ("site",
// "joint", "body", "xbody", "geom", "camera", "tendon", "actuator").
std::string object_kind(int type) { return mju_type2Str(type); }

// "is attached to site 'imu' of body 'torso'", for refusals.
std::string sensor_place(const mjModel* m, int s) {
  const int type = m->sensor_objtype[s], id = m->sensor_objid[s];
  std::string out = "is attached to " + object_kind(type) + " '" + mujoco_name(m, type, id) + "'";
  const int body = object_body(m, type, id);
  if (body >= 0 && type != mjOBJ_BODY && type != mjOBJ_XBODY)
    out += " of body '" + mujoco_name(m, mjOBJ_BODY, body) + "'";
  return out;
}
}  // namespace

// The MJCF element of each mjtSensor value (a switch, not a table: the values moved between
// MuJoCo releases as sensors were added).
const char* sensor_type_name(int type) {
  switch (type) {
    case mjSENS_TOUCH: return "touch";
    case mjSENS_ACCELEROMETER: return "accelerometer";
    case mjSENS_VELOCIMETER: return "velocimeter";
    case mjSENS_GYRO: return "gyro";
    case mjSENS_FORCE: return "force";
    case mjSENS_TORQUE: return "torque";
    case mjSENS_MAGNETOMETER: return "magnetometer";
    case mjSENS_RANGEFINDER: return "rangefinder";
    case mjSENS_JOINTPOS: return "jointpos";
    case mjSENS_JOINTVEL: return "jointvel";
    case mjSENS_TENDONPOS: return "tendonpos";
    case mjSENS_TENDONVEL: return "tendonvel";
    case mjSENS_ACTUATORPOS: return "actuatorpos";
    case mjSENS_ACTUATORVEL: return "actuatorvel";
    case mjSENS_ACTUATORFRC: return "actuatorfrc";
    case mjSENS_BALLQUAT: return "ballquat";
    case mjSENS_BALLANGVEL: return "ballangvel";
    case mjSENS_JOINTLIMITPOS: return "jointlimitpos";
    case mjSENS_JOINTLIMITVEL: return "jointlimitvel";
    case mjSENS_JOINTLIMITFRC: return "jointlimitfrc";
    case mjSENS_TENDONLIMITPOS: return "tendonlimitpos";
    case mjSENS_TENDONLIMITVEL: return "tendonlimitvel";
    case mjSENS_TENDONLIMITFRC: return "tendonlimitfrc";
    case mjSENS_FRAMEPOS: return "framepos";
    case mjSENS_FRAMEQUAT: return "framequat";
    case mjSENS_FRAMEXAXIS: return "framexaxis";
    case mjSENS_FRAMEYAXIS: return "frameyaxis";
    case mjSENS_FRAMEZAXIS: return "framezaxis";
    case mjSENS_FRAMELINVEL: return "framelinvel";
    case mjSENS_FRAMEANGVEL: return "frameangvel";
    case mjSENS_FRAMELINACC: return "framelinacc";
    case mjSENS_FRAMEANGACC: return "frameangacc";
    case mjSENS_SUBTREECOM: return "subtreecom";
    case mjSENS_SUBTREELINVEL: return "subtreelinvel";
    case mjSENS_SUBTREEANGMOM: return "subtreeangmom";
    case mjSENS_CLOCK: return "clock";
    case mjSENS_CAMPROJECTION: return "camprojection";
    case mjSENS_JOINTACTFRC: return "jointactuatorfrc";
    case mjSENS_TENDONACTFRC: return "tendonactuatorfrc";
    case mjSENS_INSIDESITE: return "insidesite";
    case mjSENS_GEOMDIST: return "distance";
    case mjSENS_GEOMNORMAL: return "normal";
    case mjSENS_GEOMFROMTO: return "fromto";
    case mjSENS_CONTACT: return "contact";
    case mjSENS_E_POTENTIAL: return "e_potential";
    case mjSENS_E_KINETIC: return "e_kinetic";
    case mjSENS_TACTILE: return "tactile";
    case mjSENS_PLUGIN: return "plugin";
    default: return "user";
  }
}

MjcfSensors::MjcfSensors(ComponentContext& c) : SimComponent(c.name(), c.sim()) {
  const mjModel* m = c.sim().m();
  const int root = c.robot().body();
  detail::Selection selection;
  selection.option = "sensors";
  selection.what = "sensor";
  selection.acting = "attached to";
  selection.names = detail::mjcf_names(m, mjOBJ_SENSOR, m->nsensor,
                                       [m](int s) { return sensor_type_name(m->sensor_type[s]); });
  for (int s = 0; s < m->nsensor; ++s) {
    selection.owned.push_back(sensor_in_subtree(m, s, root));
    // <clock>, and user sensors given no object: the scene's, not a robot's
    selection.unattached.push_back(m->sensor_objtype[s] == mjOBJ_UNKNOWN || m->sensor_objid[s] < 0);
  }
  selection.where = [m](int s) { return sensor_place(m, s); };

  description_ = json::object();
  for (int id : detail::select_objects(c, selection)) {
    const std::string& name = selection.names[id];
    if (name == "timestamp")
      c.fail("", "sensor " + std::to_string(id) +
                     " is called 'timestamp', the key get_local_data gives the "
                     "simulated time: rename it in the MJCF");
    sensors_.push_back({name, id, m->sensor_adr[id], m->sensor_dim[id]});
    names_.push_back(name);

    json entry = {{"type", sensor_type_name(m->sensor_type[id])}, {"dim", m->sensor_dim[id]}};
    const int type = m->sensor_objtype[id], object = m->sensor_objid[id];
    if (type != mjOBJ_UNKNOWN && object >= 0)
      entry[object_kind(type)] = mujoco_name(m, type, object);
    const int ref_type = m->sensor_reftype[id], ref = m->sensor_refid[id];
    if (ref_type != mjOBJ_UNKNOWN && ref >= 0)
      entry["reference"] = {{object_kind(ref_type), mujoco_name(m, ref_type, ref)}};
    if (m->sensor_cutoff[id] > 0) entry["cutoff"] = m->sensor_cutoff[id];
    description_[name] = std::move(entry);
  }
  // get_local_data inserts in name order: each insertion at the end of the map, no search
  std::sort(sensors_.begin(), sensors_.end(),
            [](const Sensor& a, const Sensor& b) { return a.name < b.name; });

  add_property("sensors", [this] { return description_; });
  add_property("count", [this] { return json(sensors_.size()); });
  add_service("get_local_data", &MjcfSensors::get_local_data)
      .doc(
          "Every sensor's value {name: number or array} and the simulated time they describe "
          "(timestamp)");
  declare_output_stream("sensors", [this] { return get_local_data(); });
}

void MjcfSensors::on_model_changed(const ModelRemap& remap) {
  for (auto& s : sensors_) {
    s.id = remap.sensor_of(s.id);
    s.address = model()->sensor_adr[s.id];
  }
}

json MjcfSensors::get_local_data() const {
  json out = json::object();
  auto& values = out.get_ref<json::object_t&>();
  const mjtNum* sensordata = data()->sensordata;
  for (const Sensor& s : sensors_) {
    const mjtNum* v = sensordata + s.address;
    if (s.dim == 1)
      values.emplace_hint(values.end(), s.name, v[0]);
    else
      values.emplace_hint(values.end(), s.name, json::array_t(v, v + s.dim));
  }
  // mj_step evaluated them on the state it started from (Simulation::state_time())
  values.emplace("timestamp", sim().state_time());
  return out;
}

SIMGATE_BUILTIN_TYPE(
    sensors,
    builtin_type<MjcfSensors>(
        "sensors", Kind::component, "the robot's MJCF <sensor>s: get_local_data {name: value}",
        "docs/components/actuators-and-sensors.md",
        {{"sensors",
          {{"type", "array"},
           {"minItems", 1},
           {"uniqueItems", true},
           {"items", {{"type", "string"}}}},
          "only these of the robot's MJCF sensors (default: every one attached to its subtree)"}}));

}  // namespace simgate::sim
