"""
The records of some topics of an indexed MCAP rosbag2 file, a chunk at a time.

The records of some topics of an indexed MCAP rosbag2 file, a chunk at a time, without a Python
object per record: the chunk is decompressed (and its CRC checked) by rosbags, its records are
located by one scan (compiled when numba is there), and the messages of a topic come out as one
array of rows when they all have the same length.  ``sins_bag`` reads its input this way; any other
storage (sqlite3, an MCAP without chunk index) is read through rosbags' reader.

Order: the messages of each topic by log time, ties in file order — the order rosbags' reader
yields them in (it sorts each chunk by log time and merges the chunks by log time and offset).
No ROS imports.
"""
from __future__ import annotations

import struct

import numpy as np

from strapdown_ros.attitude.kernel import kernels_allowed, njit_optional

__all__ = ['indexed_mcap', 'channel_ids', 'TopicRecords', 'read_topics']

_OP_MESSAGE = 0x05


def scan_python(raw, wanted):
    """
    Locate the Message records of the wanted channels in a decompressed chunk.

    Written for numba (:func:`scanner` compiles it); :func:`scan_plain` gives the same output
    without it.

    Parameters
    ----------
    raw : ndarray (n,) uint8
        The decompressed chunk.
    wanted : ndarray (m,) bool
        Indexed by channel id: True for the channels to keep.

    Returns
    -------
    ndarray (k, 5) int64
        Per message, in chunk order: record start, data start, data length, channel id, log
        time (ns).

    """
    n = raw.shape[0]
    cap = 1024
    out = np.empty((cap, 5), np.int64)
    k = 0
    pos = 0
    while pos + 9 <= n:
        op = raw[pos]
        length = 0
        for b in range(8):
            length |= np.int64(raw[pos + 1 + b]) << np.int64(8 * b)
        if op == _OP_MESSAGE and length >= 22:
            ch = np.int64(raw[pos + 9]) | (np.int64(raw[pos + 10]) << np.int64(8))
            if ch < wanted.shape[0] and wanted[ch]:
                t = np.int64(0)
                for b in range(8):
                    t |= np.int64(raw[pos + 15 + b]) << np.int64(8 * b)
                if k == cap:
                    bigger = np.empty((2 * cap, 5), np.int64)
                    bigger[:cap] = out
                    out = bigger
                    cap *= 2
                out[k, 0] = pos
                out[k, 1] = pos + 9 + 22
                out[k, 2] = length - 22
                out[k, 3] = ch
                out[k, 4] = t
                k += 1
        pos += 9 + length
    return out[:k], pos == n


_compiled = None


def scanner():
    """Return the chunk scanner: :func:`scan_python` compiled (numba), else :func:`scan_plain`."""
    global _compiled
    if _compiled is None:
        got = njit_optional(scan_python) if kernels_allowed() else None
        _compiled = got[0] if got else False
    return _compiled if _compiled is not False else scan_plain


_HEAD = struct.Struct('<BQ')
_MSG = struct.Struct('<HIq')          # log time as int64, as the compiled scan reads it


def scan_plain(raw, wanted):
    """
    Locate the Message records like :func:`scan_python`, with struct (no numba).

    Parameters
    ----------
    raw : bytes-like
        The decompressed chunk.
    wanted : sequence of bool
        Indexed by channel id: True for the channels to keep.

    Returns
    -------
    ndarray (k, 5) int64
        The same rows as :func:`scan_python`.

    """
    buf = raw.tobytes()
    n = len(buf)
    rows = []
    pos = 0
    unpack_head, unpack_msg = _HEAD.unpack_from, _MSG.unpack_from
    while pos + 9 <= n:
        op, length = unpack_head(buf, pos)
        if op == _OP_MESSAGE and length >= 22:
            ch, _, t = unpack_msg(buf, pos + 9)
            if ch < len(wanted) and wanted[ch]:
                rows.append((pos, pos + 31, length - 22, ch, t))
        pos += 9 + length
    out = np.array(rows, dtype=np.int64).reshape(-1, 5)
    return out, pos == n


def indexed_mcap(reader):
    """
    Return rosbags' MCAP storage of a reader when it can be read by chunks.

    Parameters
    ----------
    reader : rosbags.highlevel.AnyReader
        An open reader.

    Returns
    -------
    object or None
        The storage of its one MCAP file when the file has a chunk index and no per-message
        compression; else None (read through rosbags' reader).

    """
    try:
        from rosbags.rosbag2.reader import DirectoryReader
        from rosbags.rosbag2.storage_mcap import McapReader
    except ImportError:                                      # pragma: no cover - another rosbags
        return None
    inner = getattr(reader, 'readers', None)
    if not inner or len(inner) != 1:
        return None
    storage = getattr(inner[0], 'storage', None)
    if isinstance(storage, DirectoryReader):
        meta = getattr(storage, 'metadata', None)
        if meta is None or meta.compression_mode == 'message' or len(storage.storages) != 1:
            return None
        storage = storage.storages[0]
    if not isinstance(storage, McapReader) or not getattr(storage, 'chunks', None) \
            or getattr(storage, 'bio', None) is None:
        return None
    return storage


def channel_ids(storage, connections) -> dict:
    """
    Map the MCAP channel ids of these connections to their topics.

    Parameters
    ----------
    storage : object
        From :func:`indexed_mcap`.
    connections : iterable of rosbags Connection
        The connections wanted (same topic and type).

    Returns
    -------
    dict
        {MCAP channel id: topic}.

    """
    want = {(c.topic, c.msgtype) for c in connections}
    return {x.id: x.topic for x in storage.connections if (x.topic, x.msgtype) in want}


class TopicRecords:
    """
    The messages of one topic read from a chunk.

    Parameters
    ----------
    log_ns : ndarray (n,) int64
        Log times, ns.
    rows : ndarray (n, L) uint8, optional
        The messages' bytes when they all have the length L.
    records : list of bytes, optional
        The messages' bytes otherwise.

    """

    def __init__(self, log_ns, rows=None, records=None):
        self.log_ns, self.rows, self.records = log_ns, rows, records

    def __len__(self) -> int:
        return len(self.log_ns)


def read_topics(storage, channel_ids: dict, progress=None):
    """
    Yield the records of the wanted channels, chunk by chunk.

    Chunks come in the order of their first log time; within a topic, records in log time
    order, then chunk order.

    Parameters
    ----------
    storage : object
        From :func:`indexed_mcap`.
    channel_ids : dict
        {channel id: topic} (:func:`channel_ids`).
    progress : callable(int), optional
        Called with each chunk's last log time, ns.

    Yields
    ------
    dict
        {topic: TopicRecords} of one chunk.

    Raises
    ------
    ValueError
        A damaged chunk (a record running past its end, a size or checksum mismatch).

    """
    from rosbags.rosbag2.storage_mcap import decompress

    wanted = np.zeros(max(channel_ids) + 1, np.bool_)
    wanted[list(channel_ids)] = True
    scan = scanner()
    bio = storage.bio
    chunks = [c for c in storage.chunks if any(c.channel_count.get(i, 0) for i in channel_ids)]
    chunks.sort(key=lambda c: (c.message_start_time, c.chunk_start_offset))
    for chunk in chunks:
        bio.seek(chunk.chunk_start_offset + 9 + 24)
        crc = struct.unpack('<I', bio.read(4))[0]
        bio.seek(chunk.chunk_start_offset + 9 + 40 + len(chunk.compression))
        data = bio.read(chunk.compressed_size)
        if len(data) != chunk.compressed_size:
            raise ValueError(f'chunk at {chunk.chunk_start_offset}: file ends inside it')
        raw = decompress(data, chunk.compression, chunk.uncompressed_size, crc)
        buf = np.frombuffer(raw, np.uint8)
        found, whole = scan(buf, wanted)
        if not whole or (len(found) and int((found[:, 1] + found[:, 2]).max()) > len(buf)):
            raise ValueError(f'chunk at {chunk.chunk_start_offset}: a record runs past its end')
        out = {}
        for ch, topic in channel_ids.items():
            sel = found[found[:, 3] == ch]
            if not len(sel):
                continue
            sel = sel[np.argsort(sel[:, 4], kind='stable')]          # log time, then chunk order
            starts, lengths = sel[:, 1], sel[:, 2]
            if np.all(lengths == lengths[0]):
                rows = buf[starts[:, None] + np.arange(int(lengths[0]))[None, :]]
                out[topic] = TopicRecords(sel[:, 4], rows=rows)
            else:
                recs = [raw[s:s + n] for s, n in zip(starts.tolist(), lengths.tolist())]
                out[topic] = TopicRecords(sel[:, 4], records=recs)
        if progress is not None and out:
            progress(int(chunk.message_end_time))
        yield out
