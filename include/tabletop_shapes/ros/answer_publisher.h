// A frame's answer on the chain's `objects` topic. A Preprocess in this process frees the
// frame's place in flight before the answer is published (ros/frame_admission.h), so that a
// consumer that sends its next frame as soon as it has the answer is never refused as busy.
#pragma once

#include "tabletop_shapes/ros/frame_admission.h"

#include <ros/node_handle.h>
#include <ros/publisher.h>
#include <tabletop_shapes/Objects.h>

namespace tabletop_shapes {
namespace bridge {

// The chain's `objects` topic, advertised by every stage that answers frames. One second of
// answers at 30 Hz is kept per subscriber: roscpp drops the oldest message of a subscriber
// whose socket is full, and with 5 a client starved for ~150 ms (a loaded 2-core machine)
// lost "chain busy" answers, breaking "every frame admitted is answered". The first
// advertiser in a process sets the depth for all of them, hence one constant.
constexpr uint32_t kAnswersQueueSize = 30;
inline ros::Publisher advertiseAnswers(ros::NodeHandle& node) {
  return node.advertise<Objects>("objects", kAnswersQueueSize);
}

inline void publishAnswer(const ros::Publisher& publisher,
                          const boost::shared_ptr<const Objects>& objects) {
  // A busy answer is for a frame never admitted, though its stamp may repeat one in flight.
  if (!isChainBusyReason(objects->reason)) {
    frameAnsweredInProcess(publisher.getTopic(),
                           FrameAdmission::stampMicroseconds(objects->header.stamp.toNSec()));
  }
  publisher.publish(objects);
}
inline void publishAnswer(const ros::Publisher& publisher, const Objects& objects) {
  publishAnswer(publisher, boost::make_shared<const Objects>(objects));
}

}  // namespace bridge
}  // namespace tabletop_shapes
