!> Checkpoint header: the format of iem's checkpoint files (the header type, its encoding as
!> the words of the file's first 8192 bytes, the record layout text, the file's size) and the
!> checks a reader makes before trusting a file (checkpoint_read_header, checkpoint_verify).
!> Writing and reading the records is iem_checkpoint's, which re-exports this module's public
!> names.
!> Layout (format version 6; native byte order, doubles and 64-bit integers, 8-byte words):
!>   bytes 0-511: 64 integers (header_ints), bytes 512-1023: 64 reals (header_reals),
!>   bytes 1024-8191: the record layout as text (checkpoint_layout; layout_len bytes), then
!>   zeros;
!>   from byte 8192: the exact external work and damping dissipation of each rank that wrote
!>   the file (energy_words doubles a rank: each accumulator's packed state, iem_exact_sum,
!>   every value an integer below 2^53 held exactly as a double);
!>   then one record per node (global order): the registry's node record (rec_node bytes),
!>   padded with zeros to whole 8-byte words;
!>   then, when there are cell fields (rec_cell > 0), one record per cell (global order): the
!>   registry's cell record, padded likewise.
!> Integers 21-24 of the header are rec_node, rec_cell (bytes), a hash of the layout text
!> and the text's length; a file of another layout is refused (checkpoint_check_layout).
!> The file's size follows from its header exactly. Integer 17 of the header is a checksum of
!> the whole file: the XOR over every word w_i (i = 0, 1, ...: its index in the file; the
!> checksum word itself read as 0) of word_hash(i, w_i) (iem_word_hash). Each rank hashes the
!> words it writes and the results are XORed across ranks (MPI_BXOR), so the checksum does not
!> depend on the rank count; a reader hashes the file in contiguous slices, one per rank.
!> Integer 18 is the signal (15 SIGTERM, 10 SIGUSR1) after which the run stopped, 0 when the
!> run went on: job scripts read it (bytes 136-143) to tell a stop by signal from a failure.
module iem_checkpoint_header
  use iem_paths, only: mpiio_name
  use mpi_f08, only: MPI_Comm, MPI_File, MPI_Comm_rank, MPI_Comm_size, MPI_File_open, &
                     MPI_File_close, MPI_File_read_at, MPI_Bcast, MPI_Allreduce, MPI_MAX, &
                     MPI_BXOR, MPI_INTEGER, MPI_INTEGER8, MPI_DOUBLE_PRECISION, MPI_MODE_RDONLY, &
                     MPI_INFO_NULL, MPI_OFFSET_KIND, MPI_STATUS_IGNORE, MPI_IN_PLACE
  use iem_kinds, only: wp, i8
  use iem_strings, only: itoa
  use iem_exact_sum, only: exact_sum_packed_size
  use iem_fields, only: field_registry_t, field_slot_t, centre_node, centre_cell, kind_real
  use iem_word_hash, only: word_hash, text_hash
  implicit none
  private
  public :: checkpoint_header_t, checkpoint_read_header, checkpoint_verify
  public :: checkpoint_magic, checkpoint_version
  public :: checkpoint_layout, checkpoint_check_layout
  public :: header_bytes, n_header, layout_at, layout_room
  public :: record_sizes, header_ints, header_reals, layout_words

  !> The file's first word: 'CHKPTIEM' as bytes.
  integer(i8), parameter :: checkpoint_magic = 4915430829614186819_i8
  !> The format this iem writes and reads (1: before the checksum; 3: records per array,
  !> before the field registry).
  integer(i8), parameter :: checkpoint_version = 6
  !> Words of each rank's energy slot: the packed external-work and damping accumulators.
  integer, parameter, public :: energy_words = 2*exact_sum_packed_size
  !> Bytes of the header (the records start after it and the energy slots) and the number
  !> of its integers and of its reals.
  integer(i8), parameter :: header_bytes = 8192_i8, n_header = 64
  !> Byte offset and room of the layout text in the header.
  integer(i8), parameter :: layout_at = 1024_i8, layout_room = header_bytes - layout_at
  !> Largest record a header may announce (bytes).
  integer(i8), parameter :: max_record = 2_i8**26
  !> Word index of the checksum in the file (0-based).
  integer(i8), parameter :: checksum_word = 16
  !> Words a rank reads at once when checking the checksum.
  integer(i8), parameter :: read_chunk = 1048576_i8

  !> What a checkpoint records besides the node and cell records.
  type :: checkpoint_header_t
    integer(i8) :: version = checkpoint_version, nx = 0, ny = 0, n_state = 0, nonlinear = 0
    integer(i8) :: depth = 0, verlet = 0, step = 0, n_samples = 0, n_frames = 0, n_ranks = 0
    integer(i8) :: model_hash = 0, warned = 0, n_nodes = 0, n_cells = 0
    !> Bytes of a node's and of a cell's record (0: no cell records), the hash of the layout
    !> text (checkpoint_layout) and the text (as stored: at most layout_room bytes).
    integer(i8) :: rec_node = 0, rec_cell = 0, layout_hash = 0
    character(len=:), allocatable :: layout
    !> Checksum of the file (see above); the signal the run stopped on (0: none).
    integer(i8) :: checksum = 0, stop_signal = 0
    real(wp) :: t = 0.0_wp, dt = 0.0_wp, e0 = 0.0_wp, e_scale = 0.0_wp
    real(wp) :: last_balance = 0.0_wp, w_ext = 0.0_wp, w_damp = 0.0_wp
    !> The last history sample in the output when the checkpoint was written: time and the
    !> five energies (kinetic, strain, external work, damping, balance error), to recognise
    !> that output on a restart; the time of its last frame.
    real(wp) :: last_sample(7) = 0.0_wp, last_frame_time = 0.0_wp
    !> Velocity Verlet's kicks' term at the checkpoint's step (the model's kick_term, global;
    !> 0 with RK4), for the balance of a continued run's first sample.
    real(wp) :: kick = 0.0_wp
  end type checkpoint_header_t

contains

  !> Record length in the file (8-byte words) of a node and of a cell for a header.
  pure subroutine record_sizes(h, rec_n, rec_c)
    type(checkpoint_header_t), intent(in) :: h
    integer, intent(out) :: rec_n, rec_c
    rec_n = int((h%rec_node + 7)/8)
    rec_c = int((h%rec_cell + 7)/8)
  end subroutine record_sizes

  !> The record layout of reg as text, e.g. 'node: y 4 real(8), acc 2 real(8); cell: strain
  !> 12 real(8), ..., dir 12 integer(4), ...' (fields in registration order; 'none' for a
  !> centre without fields): what a checkpoint records and compares.
  function checkpoint_layout(reg) result(text)
    type(field_registry_t), intent(in) :: reg
    character(len=:), allocatable :: text
    text = 'node: '//centre_text(reg%layout(centre_node))//'; cell: '// &
           centre_text(reg%layout(centre_cell))
  contains
    function centre_text(slots) result(t)
      type(field_slot_t), intent(in) :: slots(:)
      character(len=:), allocatable :: t
      integer :: k
      t = ''
      do k = 1, size(slots)
        if (k > 1) t = t//', '
        t = t//slots(k)%name//' '//itoa(slots(k)%width)
        if (slots(k)%kind == kind_real) then
          t = t//' real('
        else
          t = t//' integer('
        end if
        t = t//itoa(slots(k)%bytes/slots(k)%width)//')'
      end do
      if (size(slots) == 0) t = 'none'
    end function centre_text
  end function checkpoint_layout

  !> Check that a checkpoint's records have the layout of reg: stat /= 0 with msg (without
  !> the path) naming both layouts otherwise.
  subroutine checkpoint_check_layout(h, reg, stat, msg)
    type(checkpoint_header_t), intent(in) :: h
    type(field_registry_t), intent(in) :: reg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=:), allocatable :: mine
    mine = checkpoint_layout(reg)
    stat = 0
    msg = ''
    if (h%layout_hash /= text_hash(mine) .or. h%rec_node /= reg%record_bytes(centre_node) .or. &
        h%rec_cell /= reg%record_bytes(centre_cell) .or. &
        h%layout /= mine(1:min(len(mine), int(layout_room)))) then
      stat = 1
      msg = 'holds records of another layout ('//h%layout//') than this run writes ('// &
            mine//'): it was written by another iem or for another kind of run'
    end if
  end subroutine checkpoint_check_layout

  !> Read and check the header of a checkpoint (rank 0 reads, every rank gets the result):
  !> an iem checkpoint of this format and these kinds, a consistent header, and exactly the
  !> size the header implies. stat /= 0 with msg (what is wrong, without the path) otherwise.
  !> The body's checksum is checkpoint_verify's.
  subroutine checkpoint_read_header(path, comm, h, stat, msg)
    character(len=*), intent(in) :: path
    type(MPI_Comm), intent(in) :: comm
    type(checkpoint_header_t), intent(out) :: h
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer(i8) :: ints(n_header), info(2), text(layout_room/8)
    real(wp) :: reals(n_header)
    integer :: rank, unit, ios
    integer(i8) :: nbytes, expect
    call MPI_Comm_rank(comm, rank)
    ints = 0
    reals = 0.0_wp
    text = 0
    ! info: (what is wrong, the file's size); what: 0 ok, 1 unreadable, 2 too short,
    ! 3 not a checkpoint
    info = 0
    if (rank == 0) then
      open(newunit=unit, file=path, access='stream', form='unformatted', action='read', &
           status='old', iostat=ios)
      if (ios /= 0) then
        info(1) = 1
      else
        inquire(unit=unit, size=info(2))
        if (info(2) < 8*2*n_header) then
          info(1) = 2
        else
          read(unit, iostat=ios) ints
          if (ios == 0) read(unit, iostat=ios) reals
          ! (a file shorter than the header's 8192 bytes is refused by its size below)
          if (ios == 0 .and. info(2) >= header_bytes) read(unit, iostat=ios) text
          if (ios /= 0) info(1) = 1
          if (ios == 0 .and. ints(1) /= checkpoint_magic) info(1) = 3
        end if
        close(unit)
      end if
    end if
    call MPI_Bcast(info, 2, MPI_INTEGER8, 0, comm)
    call MPI_Bcast(ints, int(n_header), MPI_INTEGER8, 0, comm)
    call MPI_Bcast(reals, int(n_header), MPI_DOUBLE_PRECISION, 0, comm)
    call MPI_Bcast(text, int(layout_room/8), MPI_INTEGER8, 0, comm)
    stat = int(min(info(1), 1_i8))
    nbytes = info(2)
    select case (info(1))
    case (1)
      msg = 'cannot be read'
      return
    case (2)
      if (nbytes == 0) then
        msg = 'is empty (0 bytes): not an iem checkpoint file'
      else
        msg = 'is '//itoa(nbytes)//' bytes, too short for the header of an iem checkpoint '// &
              'file (truncated, or not a checkpoint)'
      end if
      return
    case (3)
      msg = 'is not an iem checkpoint file'
      return
    end select
    h%version = ints(2); h%nx = ints(3); h%ny = ints(4); h%n_state = ints(5)
    h%nonlinear = ints(6); h%depth = ints(7); h%verlet = ints(8); h%step = ints(9)
    h%n_samples = ints(10); h%n_frames = ints(11); h%n_ranks = ints(12)
    h%model_hash = ints(13); h%warned = ints(14); h%n_nodes = ints(15); h%n_cells = ints(16)
    h%checksum = ints(17); h%stop_signal = ints(18)
    h%rec_node = ints(21); h%rec_cell = ints(22); h%layout_hash = ints(23)
    h%layout = ''
    if (ints(24) >= 0 .and. ints(24) <= layout_room) then
      h%layout = transfer(text, repeat(' ', int(layout_room)))
      h%layout = h%layout(1:ints(24))
    end if
    h%t = reals(1); h%dt = reals(2); h%e0 = reals(3); h%e_scale = reals(4)
    h%last_balance = reals(5); h%w_ext = reals(6); h%w_damp = reals(7)
    h%last_sample = reals(8:14); h%last_frame_time = reals(15); h%kick = reals(16)
    stat = 1
    if (h%version /= checkpoint_version) then
      msg = 'is an iem checkpoint of format version '//itoa(h%version)//'; this iem reads '// &
            'version '//itoa(checkpoint_version)//' only (continue it with the iem that wrote it)'
    else if (ints(19) /= storage_size(1.0_wp)/8 .or. ints(20) /= storage_size(1_i8)/8) then
      msg = 'was written with other number kinds ('//itoa(ints(19))//'-byte reals, '// &
            itoa(ints(20))//'-byte integers)'
    else if (.not. plausible(h) .or. ints(24) < 0 .or. ints(24) > layout_room) then
      msg = 'has a damaged header (inconsistent sizes or counts)'
    else
      expect = file_bytes(h)
      if (nbytes /= expect) then
        msg = 'is '//itoa(nbytes)//' bytes but its header implies '//itoa(expect)// &
              ': the file is truncated or damaged'
      else
        stat = 0
        msg = ''
      end if
    end if
  end subroutine checkpoint_read_header

  !> Check the checksum of a checkpoint whose header checkpoint_read_header has accepted: each
  !> rank hashes a contiguous slice of the file, the slices are combined. Collective; stat /= 0
  !> with msg (without the path) when the file cannot be read or does not match.
  subroutine checkpoint_verify(path, comm, h, stat, msg)
    character(len=*), intent(in) :: path
    type(MPI_Comm), intent(in) :: comm
    type(checkpoint_header_t), intent(in) :: h
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    type(MPI_File) :: fh
    integer :: rank, n_ranks, ierr, e, worst
    integer(i8) :: n_words, lo, hi, w, n, sum, j
    integer(i8), allocatable :: buf(:)
    call MPI_Comm_rank(comm, rank)
    call MPI_Comm_size(comm, n_ranks)
    stat = 0
    msg = ''
    call MPI_File_open(comm, mpiio_name(path), MPI_MODE_RDONLY, MPI_INFO_NULL, fh, ierr)
    call MPI_Allreduce(ierr, worst, 1, MPI_INTEGER, MPI_MAX, comm)
    if (worst /= 0) then
      stat = 1
      msg = 'cannot be opened'
      return
    end if
    n_words = file_bytes(h)/8
    lo = n_words*rank/n_ranks
    hi = n_words*(rank + 1)/n_ranks
    allocate(buf(min(read_chunk, max(hi - lo, 1_i8))))
    sum = 0
    w = lo
    do while (w < hi .and. ierr == 0)
      n = min(read_chunk, hi - w)
      call MPI_File_read_at(fh, int(8*w, MPI_OFFSET_KIND), buf, int(n), MPI_INTEGER8, &
                            MPI_STATUS_IGNORE, e)
      ierr = max(ierr, e)
      if (checksum_word >= w .and. checksum_word < w + n) buf(checksum_word - w + 1) = 0
      do j = 1, n
        sum = ieor(sum, word_hash(w + j - 1, buf(j)))
      end do
      w = w + n
    end do
    call MPI_File_close(fh, e)
    ierr = max(ierr, e)
    call MPI_Allreduce(ierr, worst, 1, MPI_INTEGER, MPI_MAX, comm)
    call MPI_Allreduce(MPI_IN_PLACE, sum, 1, MPI_INTEGER8, MPI_BXOR, comm)
    if (worst /= 0) then
      stat = 1
      msg = 'cannot be read'
    else if (sum /= h%checksum) then
      stat = 1
      msg = 'fails its checksum: the file is corrupted'
    end if
  end subroutine checkpoint_verify

  !> The header's integers as written (the kinds' sizes in bytes as 19 and 20).
  pure function header_ints(h) result(v)
    type(checkpoint_header_t), intent(in) :: h
    integer(i8) :: v(n_header)
    v = 0
    v(1:20) = [checkpoint_magic, h%version, h%nx, h%ny, h%n_state, h%nonlinear, h%depth, &
               h%verlet, h%step, h%n_samples, h%n_frames, h%n_ranks, h%model_hash, h%warned, &
               h%n_nodes, h%n_cells, h%checksum, h%stop_signal, &
               int(storage_size(1.0_wp)/8, i8), int(storage_size(1_i8)/8, i8)]
    v(21:23) = [h%rec_node, h%rec_cell, h%layout_hash]
    v(24) = 0
    if (allocated(h%layout)) v(24) = len(h%layout)
  end function header_ints

  !> The layout text as the words of the header's room for it (zero-padded).
  pure function layout_words(text) result(v)
    character(len=*), intent(in) :: text
    integer(i8) :: v(layout_room/8)
    character(len=layout_room) :: room
    room = repeat(achar(0), int(layout_room))
    room(1:min(len(text), int(layout_room))) = text
    v = transfer(room, 0_i8, int(layout_room/8))
  end function layout_words

  !> The header's reals as written.
  pure function header_reals(h) result(v)
    type(checkpoint_header_t), intent(in) :: h
    real(wp) :: v(n_header)
    v = 0.0_wp
    v(1:16) = [h%t, h%dt, h%e0, h%e_scale, h%last_balance, h%w_ext, h%w_damp, h%last_sample, &
               h%last_frame_time, h%kick]
  end function header_reals

  !> Whether the header's counts are consistent (a damaged header is refused before its
  !> sizes are used).
  pure logical function plausible(h)
    type(checkpoint_header_t), intent(in) :: h
    plausible = h%nx >= 1 .and. h%ny >= 1 .and. h%nx < 2_i8**30 .and. h%ny < 2_i8**30
    if (.not. plausible) return
    plausible = h%n_nodes >= 1 .and. h%n_nodes <= (h%nx + 1)*(h%ny + 1) .and. h%n_cells >= 1 .and. &
                h%n_cells <= h%nx*h%ny .and. &
                (h%n_state == 4 .or. h%n_state == 6) .and. &
                (h%nonlinear == 0 .or. h%nonlinear == 1) .and. h%depth >= 0 .and. &
                h%depth <= 10000 .and. (h%verlet == 0 .or. h%verlet == 1) .and. &
                h%step >= 0 .and. h%n_samples >= 0 .and. h%n_frames >= 0 .and. &
                h%n_ranks >= 1 .and. h%n_ranks <= 2_i8**30 .and. h%dt > 0.0_wp .and. &
                h%rec_node >= 1 .and. h%rec_node <= max_record .and. h%rec_cell >= 0 .and. &
                h%rec_cell <= max_record
  end function plausible

  !> The size in bytes of the checkpoint that header h describes.
  pure integer(i8) function file_bytes(h)
    type(checkpoint_header_t), intent(in) :: h
    integer :: rec_n, rec_c
    call record_sizes(h, rec_n, rec_c)
    file_bytes = header_bytes + 8*energy_words*h%n_ranks + 8*(rec_n*h%n_nodes + rec_c*h%n_cells)
  end function file_bytes
end module iem_checkpoint_header
