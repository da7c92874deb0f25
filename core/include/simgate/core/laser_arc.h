// simgate/core/laser_arc.h — where a laser_scanner's rays point, read from its stream's
// samples (kind "laser_scan": {range_list, point_list, timestamp}), which do not say it. Every
// transport that gives a scan its angles (foxglove.LaserScan, sensor_msgs/LaserScan) reads them
// here, one way.
//
// MORSE's scanner casts evenly spaced rays across its window, counterclockwise, centred on the
// sensor's x axis, and its point_list holds each hit in the sensor frame ([0, 0, 0] for a
// miss). Two hits give the spacing and the first ray's bearing; a scan with fewer keeps the
// last arc read (before any: 1° apart, centred, MORSE's default resolution).
//
// Life cycle: one LaserArc per stream, kept by whoever converts that stream's samples; read()
// on each scan, angles() to write it.
//
// Threads: a value; its owner's thread.
#ifndef SIMGATE_CORE_LASER_ARC_H_
#define SIMGATE_CORE_LASER_ARC_H_

#include <cstddef>

#include "simgate/core/status.h"

namespace simgate {

struct LaserArc {
  double start = 0;  // radians: the first ray's bearing
  double step = 0;   // radians between rays (0: none read yet)

  // Reads the arc of a scan of `rays` rays from its points; false (the arc kept) when it
  // could not (fewer than two hits, not `rays` points).
  bool read(const json& point_list, std::size_t rays);

  // The bearings of a scan of `rays` rays: the first and the spacing.
  struct Angles {
    double start = 0;  // radians
    double step = 0;   // radians
  };
  // The arc read, or before any MORSE's default: 1° apart, centred on the x axis.
  Angles angles(std::size_t rays) const;
};

}  // namespace simgate

#endif  // SIMGATE_CORE_LASER_ARC_H_
