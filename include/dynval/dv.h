/**
 * @file dv.h
 * @brief dynval umbrella header: every public module.
 */
#ifndef DV_H
#define DV_H

#include "dynval/dv_version.h"
#include "dynval/dv_types.h"
#include "dynval/dv_config.h"
#include "dynval/dv_moments.h"
#include "dynval/dv_sliding.h"
#include "dynval/dv_segstd.h"
#include "dynval/dv_temporal.h"
#include "dynval/dv_corr.h"
#include "dynval/dv_fft.h"
#include "dynval/dv_frf.h"
#include "dynval/dv_chan.h"
#include "dynval/dv_codec.h"
#include "dynval/dv_ar.h"
#include "dynval/dv_arx.h"
#include "dynval/dv_arstats.h"

#include "dynval/dv_mat.h"
#include "dynval/dv_elem.h"
#include "dynval/dv_model.h"
#include "dynval/dv_obs.h"

#endif /* DV_H */
