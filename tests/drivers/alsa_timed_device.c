/* A virtual audio interface for the tests, written with alsa-lib's external-plugin SDK (pcm_ioplug), as the pulse
 * and jack plugins are: a capture PCM on a clock of its own (CLOCK_MONOTONIC, optionally off by `ppm` like a real
 * crystal), whose buffer overflows when it is not read in time, exactly as a card's does. An asoundrc loads it:
 *
 *   pcm_type.nmtimed { lib "/path/libasound_module_pcm_nmtimed.so" }
 *   pcm.cell { type nmtimed rate 48000 channels 4 tone_hz 1000 amplitude 0.5 ppm 80 xrun_at_frame 24000
 *              busy_file "/tmp/x.lock" }
 *
 * Every channel carries amplitude * sin(2 pi tone_hz n / rate) of its own frame count n (S32_LE only), but for
 * sync_channel (with sync_period_us > 0): a pulse train, high (0.4) for the first 5 % of each period of the wall
 * clock (CLOCK_REALTIME: multiples of sync_period_us since 1970), low (-0.4) otherwise, each frame n taken at the
 * start's wall time + n / (rate (1 + ppm)), as a once-per-revolution pulse wired to a spare input. xrun_at_frame:
 * one overrun when the clock passes that frame (a driver thread that missed its turn). busy_file: a second open
 * while the first holds it fails with EBUSY, as a card another program holds does. */
#include <alsa/asoundlib.h>
#include <alsa/pcm_external.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/timerfd.h>
#include <time.h>
#include <unistd.h>

typedef struct {
  snd_pcm_ioplug_t io;
  int timer_fd, busy_fd;
  double ppm, tone_hz, amplitude;
  long long xrun_at, generated, sync_period_us;
  int xrun_done, sync_channel;
  struct timespec start, wall_start;
} timed_t;

static double seconds_since(const struct timespec *t0) {
  struct timespec now;
  clock_gettime(CLOCK_MONOTONIC, &now);
  return (double)(now.tv_sec - t0->tv_sec) + (double)(now.tv_nsec - t0->tv_nsec) * 1e-9;
}

static int timed_start(snd_pcm_ioplug_t *io) {
  timed_t *d = io->private_data;
  clock_gettime(CLOCK_MONOTONIC, &d->start);
  clock_gettime(CLOCK_REALTIME, &d->wall_start);
  d->generated = 0;
  double period = (double)io->period_size / (double)io->rate;
  struct itimerspec its;
  its.it_interval.tv_sec = (time_t)period;
  its.it_interval.tv_nsec = (long)((period - (double)(time_t)period) * 1e9);
  its.it_value = its.it_interval;
  return timerfd_settime(d->timer_fd, 0, &its, NULL) < 0 ? -errno : 0;
}

static int timed_stop(snd_pcm_ioplug_t *io) {
  timed_t *d = io->private_data;
  struct itimerspec off;
  memset(&off, 0, sizeof off);
  timerfd_settime(d->timer_fd, 0, &off, NULL);
  return 0;
}

/* The frames the clock has made since the start; -EPIPE once more than a buffer of them is unread. */
static snd_pcm_sframes_t timed_pointer(snd_pcm_ioplug_t *io) {
  timed_t *d = io->private_data;
  long long made = (long long)(seconds_since(&d->start) * io->rate * (1.0 + d->ppm * 1e-6));
  if (d->xrun_at >= 0 && !d->xrun_done && made >= d->xrun_at) {
    d->xrun_done = 1;
    return -EPIPE;
  }
  if (made - (long long)io->appl_ptr > (long long)io->buffer_size) return -EPIPE;
  return (snd_pcm_sframes_t)(made % (long long)io->buffer_size);
}

/* The sync channel's value at frame n: where the frame's wall-clock instant falls in its pulse period. */
static int32_t sync_sample(const timed_t *d, long long n, unsigned rate) {
  double us = (double)(d->wall_start.tv_sec % 100000) * 1e6 + (double)d->wall_start.tv_nsec * 1e-3 +
              (double)n * 1e6 / ((double)rate * (1.0 + d->ppm * 1e-6));
  double phase = fmod(us, (double)d->sync_period_us) / (double)d->sync_period_us;
  return (int32_t)lround((phase < 0.05 ? 0.4 : -0.4) * 2147483647.0);
}

static snd_pcm_sframes_t timed_transfer(snd_pcm_ioplug_t *io, const snd_pcm_channel_area_t *areas,
                                        snd_pcm_uframes_t offset, snd_pcm_uframes_t size) {
  timed_t *d = io->private_data;
  for (snd_pcm_uframes_t f = 0; f < size; ++f, ++d->generated) {
    double v = d->amplitude * sin(2.0 * M_PI * d->tone_hz * (double)d->generated / (double)io->rate);
    int32_t s = (int32_t)lround(v * 2147483647.0);
    int32_t sync = d->sync_period_us > 0 ? sync_sample(d, d->generated, io->rate) : 0;
    for (unsigned c = 0; c < io->channels; ++c) {
      char *p = (char *)areas[c].addr + (areas[c].first + areas[c].step * (offset + f)) / 8;
      memcpy(p, (int)c == d->sync_channel && d->sync_period_us > 0 ? &sync : &s, sizeof s);
    }
  }
  return (snd_pcm_sframes_t)size;
}

static int timed_poll_revents(snd_pcm_ioplug_t *io, struct pollfd *pfd, unsigned int nfds, unsigned short *revents) {
  timed_t *d = io->private_data;
  uint64_t ticks;
  (void)pfd;
  (void)nfds;
  while (read(d->timer_fd, &ticks, sizeof ticks) > 0) {
  }
  *revents = POLLIN;
  return 0;
}

static int timed_close(snd_pcm_ioplug_t *io) {
  timed_t *d = io->private_data;
  close(d->timer_fd);
  if (d->busy_fd >= 0) close(d->busy_fd);
  free(d);
  return 0;
}

static const snd_pcm_ioplug_callback_t timed_callbacks = {
    .start = timed_start,
    .stop = timed_stop,
    .pointer = timed_pointer,
    .transfer = timed_transfer,
    .poll_revents = timed_poll_revents,
    .close = timed_close,
};

static int constrain(snd_pcm_ioplug_t *io, unsigned rate, unsigned channels) {
  static const unsigned access[] = {SND_PCM_ACCESS_RW_INTERLEAVED};
  static const unsigned formats[] = {SND_PCM_FORMAT_S32_LE};
  int err;
  if ((err = snd_pcm_ioplug_set_param_list(io, SND_PCM_IOPLUG_HW_ACCESS, 1, access)) < 0 ||
      (err = snd_pcm_ioplug_set_param_list(io, SND_PCM_IOPLUG_HW_FORMAT, 1, formats)) < 0 ||
      (err = snd_pcm_ioplug_set_param_minmax(io, SND_PCM_IOPLUG_HW_CHANNELS, channels, channels)) < 0 ||
      (err = snd_pcm_ioplug_set_param_minmax(io, SND_PCM_IOPLUG_HW_RATE, rate, rate)) < 0 ||
      (err = snd_pcm_ioplug_set_param_minmax(io, SND_PCM_IOPLUG_HW_PERIOD_BYTES, 64, 1 << 20)) < 0 ||
      (err = snd_pcm_ioplug_set_param_minmax(io, SND_PCM_IOPLUG_HW_PERIODS, 2, 1024)) < 0)
    return err;
  return 0;
}

SND_PCM_PLUGIN_DEFINE_FUNC(nmtimed) {
  snd_config_iterator_t i, next;
  long rate = 48000, channels = 1, xrun_at = -1, sync_channel = -1, sync_period_us = 0;
  double ppm = 0.0, tone_hz = 1000.0, amplitude = 0.5;
  const char *busy_file = NULL;
  (void)root;
  snd_config_for_each(i, next, conf) {
    snd_config_t *n = snd_config_iterator_entry(i);
    const char *id;
    if (snd_config_get_id(n, &id) < 0) continue;
    if (!strcmp(id, "comment") || !strcmp(id, "type") || !strcmp(id, "hint")) continue;
    int err = 0;
    if (!strcmp(id, "rate")) err = snd_config_get_integer(n, &rate);
    else if (!strcmp(id, "channels")) err = snd_config_get_integer(n, &channels);
    else if (!strcmp(id, "xrun_at_frame")) err = snd_config_get_integer(n, &xrun_at);
    else if (!strcmp(id, "ppm")) err = snd_config_get_ireal(n, &ppm);
    else if (!strcmp(id, "tone_hz")) err = snd_config_get_ireal(n, &tone_hz);
    else if (!strcmp(id, "amplitude")) err = snd_config_get_ireal(n, &amplitude);
    else if (!strcmp(id, "busy_file")) err = snd_config_get_string(n, &busy_file);
    else if (!strcmp(id, "sync_channel")) err = snd_config_get_integer(n, &sync_channel);
    else if (!strcmp(id, "sync_period_us")) err = snd_config_get_integer(n, &sync_period_us);
    else {
      SNDERR("nmtimed: unknown field %s", id);
      return -EINVAL;
    }
    if (err < 0) {
      SNDERR("nmtimed: invalid value of %s", id);
      return -EINVAL;
    }
  }
  if (stream != SND_PCM_STREAM_CAPTURE) return -EINVAL;
  timed_t *d = calloc(1, sizeof *d);
  if (!d) return -ENOMEM;
  d->busy_fd = -1;
  if (busy_file) {
    d->busy_fd = open(busy_file, O_RDWR | O_CREAT | O_CLOEXEC, 0600);
    if (d->busy_fd < 0 || flock(d->busy_fd, LOCK_EX | LOCK_NB) < 0) {
      if (d->busy_fd >= 0) close(d->busy_fd);
      free(d);
      return -EBUSY;
    }
  }
  d->ppm = ppm, d->tone_hz = tone_hz, d->amplitude = amplitude, d->xrun_at = xrun_at;
  d->sync_channel = (int)sync_channel, d->sync_period_us = sync_period_us;
  d->timer_fd = timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC);
  d->io.version = SND_PCM_IOPLUG_VERSION;
  d->io.name = "noisemon timed test device";
  d->io.callback = &timed_callbacks;
  d->io.private_data = d;
  d->io.poll_fd = d->timer_fd;
  d->io.poll_events = POLLIN;
  int err = snd_pcm_ioplug_create(&d->io, name, stream, mode);
  if (err < 0) {
    close(d->timer_fd);
    if (d->busy_fd >= 0) close(d->busy_fd);
    free(d);
    return err;
  }
  if ((err = constrain(&d->io, (unsigned)rate, (unsigned)channels)) < 0) {
    snd_pcm_ioplug_delete(&d->io);
    return err;
  }
  *pcmp = d->io.pcm;
  return 0;
}

SND_PCM_PLUGIN_SYMBOL(nmtimed);
