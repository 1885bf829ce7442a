#pragma once
/// @file The one list of limits on what input may ask for (issue 19, part 2;
/// docs/reliability.md): beyond each, a value is a typo or an attack, not a setting, and
/// it is refused with a message naming the limit before anything large is allocated.
/// Here because every part of linksight links the tracker library; each limit keeps the
/// namespace of the code that enforces it.

#include <cstddef>
#include <cstdint>

namespace linksight {

// Tracker parameters (TrackerParams::validate).
inline constexpr int kMaxNodes = 1000;
inline constexpr int kMaxIterations = 1000;
inline constexpr int kMaxThreads = 1024;
/// Points with a coordinate beyond this are dropped (out of range): with at most
/// kMaxPoints points, no fixed-point sum can overflow (2^24 * 100 m * 2^32 < 2^63).
inline constexpr double kMaxCoordinate = 100.0;  // [m]
/// A frame with more usable points is lost (too_many_points).
inline constexpr std::size_t kMaxPoints = std::size_t{1} << 24;

namespace io {
/// The most pixels a depth (or label) PNG may have, 4 Mpx (8 MB decoded), checked on the
/// header before anything is decoded. The SR300's largest stream is its colour camera's
/// 1920x1080, the size of a depth image aligned to colour; this is twice that. Its depth
/// camera's own largest mode is 640x480.
inline constexpr long long kMaxDepthPngPixels = 1LL << 22;
/// The longest side of such a PNG [pixels]: twice the SR300's 1920.
inline constexpr long long kMaxDepthPngSide = 4096;
/// A PLY line (header, ASCII vertex) of this many bytes or more is refused.
inline constexpr long long kMaxPlyLine = 1LL << 16;
/// nodes.csv (score): a frame index above this is no recording's (a million frames: 9 h
/// at 30 fps), nor a node index above kMaxCsvNode (a chain has at most 100 components).
inline constexpr std::size_t kMaxCsvFrame = 1'000'000;
inline constexpr std::size_t kMaxCsvNode = 1'000;
/// The most rows a nodes.csv (an estimate, a truth) may have, 4.2 M, about 1 GB held while
/// checking: an hour at 60 fps of an 11-ball chain is 2.6 M. Within it, `score` bounds an
/// estimate by the truth's frames x nodes, and the truth by its camera.json and chain.json.
inline constexpr std::size_t kMaxCsvRows = std::size_t{1} << 22;
}  // namespace io

namespace sim {
/// Most cells a sweep may have.
inline constexpr std::size_t kMaxSweepCells = 1'000'000;
/// Most occluders a scene may have (their labels are 100 + k below 200).
inline constexpr int kMaxOccluders = 99;
/// Longest scene (duration_s) [s]: an hour at 30 fps is 108,000 frames.
inline constexpr double kMaxDurationS = 3600.0;
/// An external tracker's answer line longer than this is not a frame's nodes [bytes].
inline constexpr std::size_t kMaxAnswerBytes = std::size_t{1} << 20;
/// synth: samples per ball (a frame of 11 x 100k samples is 1.1M points) and frames.
inline constexpr int kMaxSamplesPerBall = 100'000;
inline constexpr int kMaxSynthFrames = 100'000;
namespace yaml {
/// The largest scene or grid file [bytes]: the shipped scenes are 1-5 KB, and a scene of
/// 10,000 waypoints fits. yaml-cpp holds about 110 bytes per input byte, so this bounds a
/// parse at about 120 MB.
inline constexpr std::uintmax_t kMaxFileBytes = 1u << 20;
}  // namespace yaml
}  // namespace sim

}  // namespace linksight
