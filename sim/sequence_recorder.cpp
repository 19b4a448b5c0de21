#include "sim/sequence_recorder.hpp"

#include <chrono>
#include <map>

#include "io/kestrel_sequence.hpp"

namespace kestrel::sim {

RecordStats record_sequence(Simulator& sim, const std::string& dir,
                            const std::function<void(int, int)>& progress) {
  io::KestrelSequenceWriter writer(dir, sim.calibration());
  writer.write_scenario(sim.scenario().yaml);
  RecordStats stats;
  struct Seen {
    int observations = 0;
    double first = 0.0, last = 0.0;
  };
  std::map<int, Seen> seen;
  const int total = sim.frame_count();
  for (int k = 0; k < total; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    const SimFrame f = sim.render(k);
    stats.render_seconds +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ++stats.frames;
    stats.frames_with_quarter_movers += f.mover_fraction >= 0.25;
    // The truth is written at the true exposure time; the frame at the sensor's stamp.
    writer.write_ground_truth(static_cast<Timestamp>(std::llround(f.time * 1e9)), f.body.T_w_b);
    if (!f.dropped) {
      writer.write_frame(f.stamp, f.color, f.depth, f.mask);
      ++stats.written;
      for (const SimBox& b : f.boxes) {
        io::SequenceBox sb;
        sb.t = f.stamp;
        sb.instance = b.instance;
        sb.label = b.label;
        sb.x_min = b.x_min;
        sb.y_min = b.y_min;
        sb.x_max = b.x_max;
        sb.y_max = b.y_max;
        sb.moving = b.moving;
        sb.occluded = b.occluded;
        writer.write_box(sb);
        if (b.instance >= kFirstObjectId) {
          Seen& s = seen[b.instance];
          if (s.observations++ == 0) s.first = to_seconds(f.stamp);
          s.last = to_seconds(f.stamp);
        }
      }
    }
    if (progress) progress(k + 1, total);
  }
  for (const ImuSample& s : sim.imu()) {
    writer.write_imu(s);
    ++stats.imu_samples;
  }
  std::vector<io::SequenceObject> objects;
  for (const StaticObject& o : sim.world().objects()) {
    io::SequenceObject so;
    so.id = o.id;
    so.label = o.label;
    so.center = o.center;
    so.size = o.size;
    so.yaw = o.yaw;
    if (const auto it = seen.find(o.id); it != seen.end()) {
      so.observations = it->second.observations;
      so.first_seen = it->second.first;
      so.last_seen = it->second.last;
    }
    objects.push_back(so);
  }
  writer.write_objects(objects);
  writer.close();
  return stats;
}

}  // namespace kestrel::sim
