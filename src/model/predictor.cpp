#include "model/predictor.h"

#include "common/stopwatch.h"
#include "model/checkpoint.h"
#include "model/default_model.h"
#include "model/device.h"
#include "model/inference.h"

namespace ii {

Predictor::Predictor(const std::string& checkpoint, const torch::Device& device, Precision precision)
    : model_name_(checkpoint.empty() ? kDefaultModelName : checkpoint),
      device_(device),
      precision_(precision),
      network_([&] {
        Checkpoint ck = checkpoint_or_default(checkpoint);
        format_ = ck.format;
        Network network = network_from_checkpoint(std::move(ck), model_name_);
        network.to(device);
        return network;
      }()) {}

nlohmann::json Predictor::describe() const {
  return {{"checkpoint", model_name_}, {"format", format_}, {"config", config().to_json()}};
}

Prediction Predictor::predict(const Scene& scene, const SceneInputOptions& options) const {
  Prediction p;
  Stopwatch watch;
  p.input = prepare_scene_input(scene, options);
  check_model_fits_input(config(), p.input.input, model_name_);
  p.prepare_ms = watch.lap();
  upload_network_inputs(p.input.input, device_);
  synchronize(device_);
  p.upload_ms = watch.lap();
  p.maps = run_network(network_, p.input.input, precision_);
  synchronize(device_);
  p.network_ms = watch.lap();
  return p;
}

}  // namespace ii
