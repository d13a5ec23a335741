#pragma once
// For the files of dataset/scene/ only: defines a source's factory with the
// name the registry (registry.inc) expects.

#include <memory>

#include "dataset/scene_source.h"

#define GEODRIVE_DEFINE_SCENE_SOURCE(identifier, Class)           \
  std::unique_ptr<::geodrive::SceneSource> CreateSceneSource_##identifier() { \
    return std::make_unique<Class>();                             \
  }
