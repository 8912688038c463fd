#include "pedicle_drilling/core/breathing/identification_window.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace pedicle_drilling::core {

IdentificationWindow::IdentificationWindow(double window_s) : window_s_(window_s) {
  if (!(window_s > 0.0 && window_s <= 3600.0)) {
    throw std::invalid_argument("window_s: must be in (0, 3600] s");
  }
}

double IdentificationWindow::advance(double t) {
  double jump = 0.0;
  if (t + 1.0 < latest_t_) {  // time went back: what was recorded belongs to another run
    jump = latest_t_ - t;
    tv_.clear();
    marker_.clear();
    latest_t_ = t;
  }
  latest_t_ = std::max(latest_t_, t);
  const double oldest = latest_t_ - window_s_;
  while (!tv_.empty() && tv_.front().first < oldest) tv_.pop_front();
  while (!marker_.empty() && marker_.front().t < oldest) marker_.pop_front();
  return jump;
}

double IdentificationWindow::addTidalVolume(double t, double volume_ml) {
  const double jump = advance(t);
  if (tv_.empty() || t > tv_.back().first) tv_.emplace_back(t, volume_ml);
  return jump;
}

double IdentificationWindow::addMarker(double t, const std::array<double, 3>& d_mm) {
  const double jump = advance(t);
  if (marker_.empty() || t > marker_.back().t) marker_.push_back({t, d_mm});
  return jump;
}

WindowRecording IdentificationWindow::take() const {
  WindowRecording out;
  if (tv_.size() < 2) {
    std::ostringstream text;
    text << "no tidal volume: " << tv_.size() << " samples received in the last " << window_s_
         << " s";
    out.error = text.str();
    return out;
  }
  for (const auto& [t, v] : tv_) {
    if (!std::isfinite(v)) {
      std::ostringstream text;
      text << "tidal volume sample at t = " << t
           << " s is not finite (NaN or inf); identification refused";
      out.error = text.str();
      return out;
    }
    out.recording.t_tv.push_back(t);
    out.recording.tv.push_back(v);
  }
  const double first = tv_.front().first;
  const double last = tv_.back().first;
  for (const Marker& m : marker_) {
    if (m.t < first || m.t > last) continue;  // pairing needs the volume around it
    out.recording.t_disp.push_back(m.t);
    out.recording.ap.push_back(m.d_mm[0]);
    out.recording.si.push_back(m.d_mm[1]);
    out.recording.lr.push_back(m.d_mm[2]);
  }
  if (out.recording.t_disp.size() < kMinMarkers) {
    out.error = "too few marker samples: " + std::to_string(out.recording.t_disp.size()) +
                " inside the tidal-volume window (need >= " + std::to_string(kMinMarkers) + ")";
    return out;
  }
  out.ok = true;
  return out;
}

}  // namespace pedicle_drilling::core
