// Segments one PCD file with the installed library and round-trips its label image through
// the installed LCM bindings and label image codec; prints one line a test can check:
//   consumer: <objects> objects, <supervoxels> supervoxels, labels round trip ok
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "clutterseg/core/thread_pool.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/label_image_codec.hpp"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/pipeline/segmenter.h"
#include "clutterseg/version.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: consumer FRAME.pcd\n");
    return 2;
  }
  try {
    const clutterseg::core::PointCloud cloud = clutterseg::io::ReadPcd(argv[1]);
    clutterseg::core::ThreadPool pool(2);
    clutterseg::pipeline::Segmenter segmenter(clutterseg::pipeline::SegmenterParams{}, &pool);
    clutterseg::pipeline::SegmentationResult result;
    segmenter.Process(cloud, clutterseg::core::DefaultKinectIntrinsics(), &result);

    clutterseg::label_image_t msg{};
    std::string error;
    if (!clutterseg::EncodeLabelImage(
            result.labels.data.data(), result.labels.width, result.labels.height,
            clutterseg::label_image_t::COMPRESSION_RLE, &msg, nullptr, &error)) {
      std::fprintf(stderr, "consumer: encode: %s\n", error.c_str());
      return 1;
    }
    std::vector<uint8_t> bytes(static_cast<size_t>(msg.getEncodedSize()));
    msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    clutterseg::label_image_t back{};
    back.decode(bytes.data(), 0, static_cast<int>(bytes.size()));
    std::vector<uint32_t> ids;
    if (!clutterseg::DecodeLabelImage(back, &ids, &error) || ids != result.labels.data) {
      std::fprintf(stderr, "consumer: labels do not round trip: %s\n", error.c_str());
      return 1;
    }
    clutterseg::objects_t objects{};
    objects.num_objects = static_cast<int32_t>(result.objects.size());
    objects.objects.resize(result.objects.size());
    std::printf("consumer (clutterseg %s): %zu objects, %u supervoxels, labels round trip ok\n",
                clutterseg::kVersion, result.objects.size(), result.num_supervoxels);
    return result.objects.empty() ? 1 : 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "consumer: %s\n", e.what());
    return 1;
  }
}
