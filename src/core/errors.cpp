#include "meshpde/core/errors.h"

// The hierarchy is header-only; this file anchors it in the library so that the
// type information lives in one shared object.
namespace meshpde {}
