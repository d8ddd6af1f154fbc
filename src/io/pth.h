#pragma once
// PyTorch `.pth` checkpoints read without Python: the zip container torch.save writes since
// 1.6 (`<name>/data.pkl`, `<name>/data/<key>` storages, `<name>/byteorder`, `<name>/version`)
// and the older legacy stream (magic, protocol and system-info pickles, the main pickle, the
// storage key list, then each storage as an int64 element count and raw data). Pickles go
// through the restricted unpickler of io/pickle.h: only tensors, containers and plain values
// come out, any other global is refused, nothing is ever executed.
#include <filesystem>
#include <map>
#include <string>

#include "io/pickle.h"

namespace ii {

// The whole object tree of a checkpoint. Every tensor is checked against its storage: the
// storage exists, holds exactly its declared element count, and contains the whole view.
PickleValue read_pth(const std::filesystem::path& path, const PickleOptions& options = {});

// Every tensor in nested dicts (and lists), under dotted keys ("gaudecoder.module.blocks.0...");
// non-tensor leaves (training arguments, epoch) are ignored.
std::map<std::string, PthTensor> read_pth_tensors(const std::filesystem::path& path, const PickleOptions& options = {});

// Everything that is not a tensor (training arguments, epoch, ...), as JSON text.
std::string read_pth_extras_json(const std::filesystem::path& path);

}  // namespace ii
