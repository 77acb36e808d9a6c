// See include/tabletop_shapes/ros/cloud_input.h.
#include "tabletop_shapes/ros/cloud_input.h"

#include "tabletop_shapes/core/parallel.h"

#include <pcl_conversions/pcl_conversions.h>
#include <pcl_ros/point_cloud.h>
#include <ros/subscription_callback_helper.h>

#include <algorithm>
#include <atomic>
#include <cstring>

#ifdef __SSE2__
#include <emmintrin.h>
#endif

namespace tabletop_shapes {
namespace bridge {

namespace {

const sensor_msgs::PointField* findField(const sensor_msgs::PointCloud2& msg, const char* name) {
  const auto field = std::find_if(msg.fields.begin(), msg.fields.end(),
                                  [&](const sensor_msgs::PointField& f) { return f.name == name; });
  return field == msg.fields.end() ? nullptr : &*field;
}

// Reads little-endian values from a buffer, never past its end.
class BoundedReader {
 public:
  BoundedReader(const uint8_t* data, size_t size) : data_(data), left_(size) {}
  template <typename T>
  bool read(T& value) {
    if (left_ < sizeof(T)) return false;
    std::memcpy(&value, data_, sizeof(T));
    data_ += sizeof(T);
    left_ -= sizeof(T);
    return true;
  }
  // A length-prefixed byte sequence (string or uint8[]).
  template <typename Bytes>
  bool readBytes(Bytes& bytes) {
    const uint8_t* start = nullptr;
    size_t length = 0;
    if (!skipBytes(start, length)) return false;
    bytes.assign(start, start + length);
    return true;
  }
  // The same, left where it is: `start` and `length` locate it.
  bool skipBytes(const uint8_t*& start, size_t& length) {
    uint32_t claimed = 0;
    if (!read(claimed) || claimed > left_) return false;
    start = data_;
    length = claimed;
    data_ += claimed;
    left_ -= claimed;
    return true;
  }
  // An array length, checked against the bytes left for elements of at least `min_bytes`.
  bool readCount(uint32_t& count, size_t min_bytes) {
    return read(count) && count <= left_ / min_bytes;
  }
  size_t left() const { return left_; }

 private:
  const uint8_t* data_;
  size_t left_;
};

using CloudCallbackParameter = const boost::shared_ptr<const InputCloud>&;

// roscpp calls deserialize() only for a message that did not arrive as an InputCloud object
// (the pointer path skips it), on the subscriber's callback queue right before call(); a null
// result drops the message before the callback.
class InputCloudHelper : public ros::SubscriptionCallbackHelperT<CloudCallbackParameter> {
 public:
  InputCloudHelper(const InputCloudCallbacks& callbacks, uint64_t max_points)
      : ros::SubscriptionCallbackHelperT<CloudCallbackParameter>(callbacks.on_shared),
        callbacks_(callbacks),
        max_points_(max_points) {}

  // A cloud read by deserialize() was admitted there; one handed over by pointer is asked here.
  void call(ros::SubscriptionCallbackHelperCallParams& params) override {
    const boost::shared_ptr<const void> message = params.event.getConstMessage();
    if (message.get() == read_here_) {
      callbacks_.on_received(boost::static_pointer_cast<const ReceivedCloud>(message));
      return;
    }
    if (callbacks_.admit) {
      const auto* input = static_cast<const InputCloud*>(message.get());
      if (!callbacks_.admit(pcl_conversions::fromPCL(input->header))) return;
    }
    ros::SubscriptionCallbackHelperT<CloudCallbackParameter>::call(params);
  }

  ros::VoidConstPtr deserialize(
      const ros::SubscriptionCallbackHelperDeserializeParams& params) override {
    // The points are read straight from roscpp's buffer: no intermediate PointCloud2 copy.
    sensor_msgs::PointCloud2 layout;
    const uint8_t* points = nullptr;
    size_t point_bytes = 0;
    const std::string unreadable =
        deserializeCloudLayout(params.buffer, params.length, layout, points, point_bytes);
    if (!unreadable.empty()) {
      callbacks_.on_invalid(layout.header, "unreadable message: " + unreadable);
      return {};
    }
    const std::string invalid = invalidCloudReason(layout, point_bytes, max_points_);
    if (!invalid.empty()) {
      callbacks_.on_invalid(layout.header, invalid);
      return {};
    }
    // Before the points are read: a refused frame costs no more than its header.
    if (callbacks_.admit && !callbacks_.admit(layout.header)) return {};
    const boost::shared_ptr<ReceivedCloud> cloud =
        clouds_.next(static_cast<size_t>(layout.width) * layout.height);
    readInputCloud(layout, points, *cloud);
    read_here_ = cloud.get();
    return cloud;
  }

 private:
  InputCloudCallbacks callbacks_;
  uint64_t max_points_;
  CloudPool<pcl::PointXYZ> clouds_;  // one read while Preprocess holds the last
  // The last cloud deserialize() read and admitted (same callback thread as call()).
  std::atomic<const void*> read_here_{nullptr};
};

}  // namespace

std::string deserializeCloud(const uint8_t* data, size_t size, sensor_msgs::PointCloud2& msg) {
  const uint8_t* points = nullptr;
  size_t point_bytes = 0;
  const std::string unreadable = deserializeCloudLayout(data, size, msg, points, point_bytes);
  if (unreadable.empty()) msg.data.assign(points, points + point_bytes);
  return unreadable;
}

std::string deserializeCloudLayout(const uint8_t* data, size_t size, sensor_msgs::PointCloud2& msg,
                                   const uint8_t*& points, size_t& point_bytes) {
  BoundedReader in(data, size);
  // A field takes at least 13 bytes: name length, offset, datatype, count.
  uint32_t fields = 0;
  if (!in.read(msg.header.seq) || !in.read(msg.header.stamp.sec) ||
      !in.read(msg.header.stamp.nsec) || !in.readBytes(msg.header.frame_id) ||
      !in.read(msg.height) || !in.read(msg.width) || !in.readCount(fields, 13)) {
    return "header cut short";
  }
  msg.fields.resize(fields);
  for (sensor_msgs::PointField& field : msg.fields) {
    if (!in.readBytes(field.name) || !in.read(field.offset) || !in.read(field.datatype) ||
        !in.read(field.count)) {
      return "fields cut short";
    }
  }
  if (!in.read(msg.is_bigendian) || !in.read(msg.point_step) || !in.read(msg.row_step)) {
    return "steps cut short";
  }
  if (!in.skipBytes(points, point_bytes)) {
    return "data cut short (its length exceeds the message)";
  }
  if (!in.read(msg.is_dense)) return "is_dense missing";
  if (in.left() != 0) return std::to_string(in.left()) + " bytes after the cloud";
  return "";
}

std::string invalidCloudReason(const sensor_msgs::PointCloud2& msg, uint64_t max_points) {
  return invalidCloudReason(msg, msg.data.size(), max_points);
}

std::string invalidCloudReason(const sensor_msgs::PointCloud2& msg, size_t point_bytes,
                               uint64_t max_points) {
  const auto str = [](uint64_t value) { return std::to_string(value); };
  // Sizes first, before anything walks the data: a 108-byte message declaring width 0 and
  // height 2^32-1 once stalled the chain for seconds.
  const uint64_t points = static_cast<uint64_t>(msg.width) * msg.height;
  if (points == 0 && (msg.width > 1 || msg.height > 1)) {
    return "width " + str(msg.width) + " x height " + str(msg.height) +
           ": an empty cloud is 0 x 0, 0 x 1 or 1 x 0";
  }
  if (points > max_points) {
    return str(points) + " points (" + str(msg.width) + " x " + str(msg.height) +
           ") is above max_points " + str(max_points);
  }
  if (msg.is_bigendian) return "big-endian data";
  for (const char* axis : {"x", "y", "z"}) {
    const sensor_msgs::PointField* field = findField(msg, axis);
    if (!field) return std::string("no field '") + axis + "'";
    if (field->datatype != sensor_msgs::PointField::FLOAT32) {
      return std::string("field '") + axis + "' is not FLOAT32";
    }
    if (static_cast<uint64_t>(field->offset) + 4 > msg.point_step) {
      return std::string("field '") + axis + "' at offset " + str(field->offset) +
             " overflows point_step " + str(msg.point_step);
    }
  }
  if (static_cast<uint64_t>(msg.point_step) * msg.width > msg.row_step) {
    return "row_step " + str(msg.row_step) + " is shorter than width " + str(msg.width) +
           " x point_step " + str(msg.point_step);
  }
  const uint64_t declared = static_cast<uint64_t>(msg.row_step) * msg.height;
  if (declared > point_bytes) {
    return "data shorter than declared: " + str(point_bytes) + " bytes, row_step " +
           str(msg.row_step) + " x height " + str(msg.height) + " = " + str(declared);
  }
  if (declared < point_bytes) {
    return "data longer than declared: " + str(point_bytes) + " bytes, row_step " +
           str(msg.row_step) + " x height " + str(msg.height) + " = " + str(declared);
  }
  return "";
}

void readInputCloud(const sensor_msgs::PointCloud2& msg, ReceivedCloud& cloud) {
  readInputCloud(msg, msg.data.data(), cloud);
}

void readInputCloud(const sensor_msgs::PointCloud2& msg, const uint8_t* points,
                    ReceivedCloud& cloud) {
  cloud.header = pcl_conversions::toPCL(msg.header);
  cloud.width = msg.width;
  cloud.height = msg.height;
  cloud.is_dense = msg.is_dense;
  // A reused cloud of the same size constructs nothing here; every point is written below.
  const size_t size = static_cast<size_t>(msg.width) * msg.height;
  cloud.points.resize(size);
  const uint32_t offset_x = findField(msg, "x")->offset, offset_y = findField(msg, "y")->offset,
                 offset_z = findField(msg, "z")->offset;
  // In bands of points on the free cores: the copy is bound by memory traffic (a VGA camera
  // cloud is 10 MB of 32-byte points), which two cores move faster than one, and the chain is
  // idle while a frame is read.
  constexpr size_t kPointsPerBand = 32768;
  const size_t bands = (size + kPointsPerBand - 1) / kPointsPerBand;
  const size_t point_step = msg.point_step;
  // x y z first and at least 16 bytes a point (every camera driver's and PCL's layouts): a
  // point is one 16-byte load and store, its fourth lane set to 1.
  const bool xyz_first = offset_x == 0 && offset_y == 4 && offset_z == 8 && point_step >= 16;
  parallelFor(
      bands,
      [&](size_t band) {
        const size_t end = std::min(size, (band + 1) * kPointsPerBand);
        // Row by row: rows may end in padding (row_step > width x point_step).
        for (size_t i = band * kPointsPerBand; i < end;) {
          const size_t row = i / msg.width, row_end = std::min(end, (row + 1) * msg.width);
          const uint8_t* point = points + row * msg.row_step + (i - row * msg.width) * point_step;
          pcl::PointXYZ* out = cloud.points.data() + i;
#ifdef __SSE2__
          if (xyz_first) {
            const __m128 xyz = _mm_castsi128_ps(_mm_setr_epi32(-1, -1, -1, 0));
            const __m128 one = _mm_setr_ps(0.0f, 0.0f, 0.0f, 1.0f);
            for (; i < row_end; ++i, ++out, point += point_step) {
              const __m128 loaded = _mm_loadu_ps(reinterpret_cast<const float*>(point));
              _mm_storeu_ps(out->data, _mm_or_ps(_mm_and_ps(loaded, xyz), one));
            }
            continue;
          }
#endif
          for (; i < row_end; ++i, ++out, point += point_step) {
            std::memcpy(&out->x, point + offset_x, 4);
            std::memcpy(&out->y, point + offset_y, 4);
            std::memcpy(&out->z, point + offset_z, 4);
            out->data[3] = 1.0f;  // as a constructed point: PCL's 4-vector maps read it
          }
        }
      },
      freeWorkerThreads());
}

ros::Subscriber subscribeInputCloud(ros::NodeHandle& node, const std::string& topic,
                                    uint32_t queue_size, const InputCloudCallbacks& callbacks,
                                    uint64_t max_points) {
  ros::SubscribeOptions options;
  // Topic type and checksum are PointCloud2's (pcl_ros's traits); the helper does the rest.
  options.init<InputCloud>(topic, queue_size, callbacks.on_shared);
  options.helper = boost::make_shared<InputCloudHelper>(callbacks, max_points);
  return node.subscribe(options);
}

}  // namespace bridge
}  // namespace tabletop_shapes
