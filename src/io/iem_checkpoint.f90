!> Checkpoint files: the whole state of a dynamic run in one binary file written with MPI-IO,
!> in global node and cell order, so a run can continue from it on any number of ranks.
!> Layout (little-endian as written, native doubles and 64-bit integers):
!>   bytes 0-511: 64 integers (header_t's integers), bytes 512-1023: 64 reals;
!>   from byte 8192: (w_ext, w_damp) of each rank that wrote the file;
!>   then one record per node (global order): y(1:n_state), acc(1:n_state-2);
!>   then, with nonlinear springs, one record per cell (global order): for each of its 12
!>   springs strain, stress, dir, count, e_max_pos, e_max_neg, work, e_rev(1:D), s_rev(1:D).
!> A file is written as <path>.tmp and renamed to <path> once complete, so a crash while
!> writing leaves the previous checkpoint intact.
module iem_checkpoint
  use, intrinsic :: iso_c_binding, only: c_int, c_char, c_null_char
  use mpi_f08, only: MPI_Comm, MPI_File, MPI_Datatype, MPI_Status, MPI_Comm_rank, &
                     MPI_Comm_size, MPI_File_open, MPI_File_close, MPI_File_set_view, &
                     MPI_File_write_at, MPI_File_read_at, MPI_File_write_all, MPI_File_read_all, &
                     MPI_Type_create_hindexed, MPI_Type_commit, MPI_Type_free, MPI_Bcast, &
                     MPI_Barrier, MPI_Allreduce, MPI_MAX, MPI_INTEGER, MPI_INTEGER8, &
                     MPI_DOUBLE_PRECISION, MPI_MODE_CREATE, MPI_MODE_WRONLY, MPI_MODE_RDONLY, &
                     MPI_INFO_NULL, MPI_OFFSET_KIND, MPI_ADDRESS_KIND, MPI_STATUS_IGNORE
  use iem_kinds, only: wp, i8
  use iem_strings, only: itoa
  implicit none
  private
  public :: checkpoint_header_t, checkpoint_write, checkpoint_read_header, checkpoint_read
  public :: checkpoint_magic

  integer(i8), parameter :: checkpoint_magic = 4915430829614186819_i8  ! 'CHKPTIEM' as bytes
  integer(i8), parameter :: header_bytes = 8192_i8, n_header = 64

  !> What a checkpoint records besides the node and cell records.
  type :: checkpoint_header_t
    integer(i8) :: version = 1, nx = 0, ny = 0, n_state = 0, nonlinear = 0, depth = 0
    integer(i8) :: verlet = 0, step = 0, n_samples = 0, n_frames = 0, n_ranks = 0
    integer(i8) :: model_hash = 0, warned = 0, n_nodes = 0, n_cells = 0
    real(wp) :: t = 0.0_wp, dt = 0.0_wp, e0 = 0.0_wp, e_scale = 0.0_wp
    real(wp) :: last_balance = 0.0_wp, w_ext = 0.0_wp, w_damp = 0.0_wp
  end type checkpoint_header_t

  interface
    function c_rename(old, new) bind(C, name='rename') result(r)
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: old(*), new(*)
      integer(c_int) :: r
    end function c_rename
  end interface

contains

  !> Record length (doubles) of a node and of a cell for a header.
  pure subroutine record_sizes(h, rec_n, rec_c)
    type(checkpoint_header_t), intent(in) :: h
    integer, intent(out) :: rec_n, rec_c
    rec_n = int(2*h%n_state - 2)
    rec_c = 0
    if (h%nonlinear /= 0) rec_c = int(12*(7 + 2*h%depth))
  end subroutine record_sizes

  !> Write a checkpoint collectively: the header, this rank's (w_ext, w_damp), its owned node
  !> records node_rec(:, k) at the ascending global indices owned_gids(k), and its cell
  !> records cell_rec(:, k) at the ascending global cell indices cell_gids(k) (each cell
  !> written by one rank). stat /= 0 with msg on every rank on failure.
  subroutine checkpoint_write(path, comm, h, energy, owned_gids, node_rec, cell_gids, &
                              cell_rec, stat, msg)
    character(len=*), intent(in) :: path
    type(MPI_Comm), intent(in) :: comm
    type(checkpoint_header_t), intent(in) :: h
    real(wp), intent(in) :: energy(2)
    integer(i8), intent(in) :: owned_gids(:), cell_gids(:)
    real(wp), intent(inout) :: node_rec(:, :), cell_rec(:, :)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    type(MPI_File) :: fh
    integer :: rank, ierr, ierr2, rec_n, rec_c
    integer(MPI_OFFSET_KIND) :: off_n, off_c
    character(len=:), allocatable :: tmp

    call MPI_Comm_rank(comm, rank)
    call record_sizes(h, rec_n, rec_c)
    tmp = path//'.tmp'
    stat = 0
    msg = ''
    call MPI_File_open(comm, tmp, ior(MPI_MODE_CREATE, MPI_MODE_WRONLY), MPI_INFO_NULL, fh, &
                       ierr)
    call agree(ierr, 'cannot create '//tmp)
    if (stat /= 0) return
    if (rank == 0) call MPI_File_write_at(fh, 0_MPI_OFFSET_KIND, header_ints(h), &
                                          int(n_header), MPI_INTEGER8, MPI_STATUS_IGNORE, ierr)
    if (rank == 0) call MPI_File_write_at(fh, int(8*n_header, MPI_OFFSET_KIND), header_reals(h), &
                                          int(n_header), MPI_DOUBLE_PRECISION, &
                                          MPI_STATUS_IGNORE, ierr)
    call MPI_File_write_at(fh, header_bytes + 16_MPI_OFFSET_KIND*rank, energy, 2, &
                           MPI_DOUBLE_PRECISION, MPI_STATUS_IGNORE, ierr2)
    ierr = max(ierr, ierr2)
    off_n = header_bytes + 16_MPI_OFFSET_KIND*h%n_ranks
    off_c = off_n + 8_MPI_OFFSET_KIND*rec_n*h%n_nodes
    call transfer(fh, off_n, rec_n, owned_gids, node_rec, .true., ierr2)
    ierr = max(ierr, ierr2)
    if (rec_c > 0) then
      call transfer(fh, off_c, rec_c, cell_gids, cell_rec, .true., ierr2)
      ierr = max(ierr, ierr2)
    end if
    call MPI_File_close(fh, ierr2)
    call agree(max(ierr, ierr2), 'writing '//tmp//' failed')
    if (stat /= 0) return
    call MPI_Barrier(comm)
    ierr = 0
    if (rank == 0) ierr = c_rename(tmp//c_null_char, path//c_null_char)
    call MPI_Bcast(ierr, 1, MPI_INTEGER, 0, comm)
    if (ierr /= 0) then
      stat = 1
      msg = 'cannot rename '//tmp//' to '//path
    end if

  contains

    subroutine agree(e, what)
      integer, intent(in) :: e
      character(len=*), intent(in) :: what
      integer :: worst
      call MPI_Allreduce(e, worst, 1, MPI_INTEGER, MPI_MAX, comm)
      if (worst /= 0) then
        stat = 1
        msg = 'checkpoint: '//what
      end if
    end subroutine agree
  end subroutine checkpoint_write

  !> Read the header of a checkpoint (rank 0 reads, every rank gets it); stat /= 0 with msg
  !> when the file cannot be read or is not an iem checkpoint.
  subroutine checkpoint_read_header(path, comm, h, stat, msg)
    character(len=*), intent(in) :: path
    type(MPI_Comm), intent(in) :: comm
    type(checkpoint_header_t), intent(out) :: h
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer(i8) :: ints(n_header)
    real(wp) :: reals(n_header)
    integer :: rank, ios
    logical :: exists
    call MPI_Comm_rank(comm, rank)
    stat = 0
    msg = ''
    ints = 0
    reals = 0.0_wp
    if (rank == 0) then
      inquire(file=path, exist=exists)
      stat = 1
      if (exists) then
        open(newunit=ios, file=path, access='stream', form='unformatted', action='read', &
             status='old', iostat=stat)
        if (stat == 0) then
          read(ios, iostat=stat) ints
          if (stat == 0) read(ios, iostat=stat) reals
          close(ios)
          ! too short for a header, or not ours
          if (stat /= 0 .or. ints(1) /= checkpoint_magic) stat = 2
        else
          stat = 1
        end if
      end if
    end if
    call MPI_Bcast(stat, 1, MPI_INTEGER, 0, comm)
    if (stat == 1) then
      msg = 'cannot read '//path
      return
    else if (stat == 2) then
      msg = path//' is not an iem checkpoint file'
      return
    end if
    call MPI_Bcast(ints, int(n_header), MPI_INTEGER8, 0, comm)
    call MPI_Bcast(reals, int(n_header), MPI_DOUBLE_PRECISION, 0, comm)
    h%version = ints(2); h%nx = ints(3); h%ny = ints(4); h%n_state = ints(5)
    h%nonlinear = ints(6); h%depth = ints(7); h%verlet = ints(8); h%step = ints(9)
    h%n_samples = ints(10); h%n_frames = ints(11); h%n_ranks = ints(12)
    h%model_hash = ints(13); h%warned = ints(14); h%n_nodes = ints(15); h%n_cells = ints(16)
    h%t = reals(1); h%dt = reals(2); h%e0 = reals(3); h%e_scale = reals(4)
    h%last_balance = reals(5); h%w_ext = reals(6); h%w_damp = reals(7)
  end subroutine checkpoint_read_header

  !> Read the node records of owned_gids and the cell records of cell_gids (both ascending)
  !> and this rank's (w_ext, w_damp): its own when the file was written on as many ranks,
  !> else the totals on rank 0 and zeros elsewhere. Collective.
  subroutine checkpoint_read(path, comm, h, energy, owned_gids, node_rec, cell_gids, cell_rec, &
                             stat, msg)
    character(len=*), intent(in) :: path
    type(MPI_Comm), intent(in) :: comm
    type(checkpoint_header_t), intent(in) :: h
    real(wp), intent(out) :: energy(2)
    integer(i8), intent(in) :: owned_gids(:), cell_gids(:)
    real(wp), intent(out) :: node_rec(:, :), cell_rec(:, :)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    type(MPI_File) :: fh
    integer :: rank, n_ranks, ierr, ierr2, rec_n, rec_c, worst
    integer(MPI_OFFSET_KIND) :: off_n, off_c
    call MPI_Comm_rank(comm, rank)
    call MPI_Comm_size(comm, n_ranks)
    call record_sizes(h, rec_n, rec_c)
    stat = 0
    msg = ''
    energy = 0.0_wp
    call MPI_File_open(comm, path, MPI_MODE_RDONLY, MPI_INFO_NULL, fh, ierr)
    call MPI_Allreduce(ierr, worst, 1, MPI_INTEGER, MPI_MAX, comm)
    if (worst /= 0) then
      stat = 1
      msg = 'cannot open '//path
      return
    end if
    ierr = 0
    if (h%n_ranks == n_ranks) then
      call MPI_File_read_at(fh, header_bytes + 16_MPI_OFFSET_KIND*rank, energy, 2, &
                            MPI_DOUBLE_PRECISION, MPI_STATUS_IGNORE, ierr)
    else if (rank == 0) then
      energy = [h%w_ext, h%w_damp]
    end if
    off_n = header_bytes + 16_MPI_OFFSET_KIND*h%n_ranks
    off_c = off_n + 8_MPI_OFFSET_KIND*rec_n*h%n_nodes
    call transfer(fh, off_n, rec_n, owned_gids, node_rec, .false., ierr2)
    ierr = max(ierr, ierr2)
    if (rec_c > 0) then
      call transfer(fh, off_c, rec_c, cell_gids, cell_rec, .false., ierr2)
      ierr = max(ierr, ierr2)
    end if
    call MPI_File_close(fh, ierr2)
    call MPI_Allreduce(max(ierr, ierr2), worst, 1, MPI_INTEGER, MPI_MAX, comm)
    if (worst /= 0) then
      stat = 1
      msg = 'reading '//path//' failed'
    end if
  end subroutine checkpoint_read

  !> Collective write (or read) of records rec(:, k) of length n at the global indices
  !> gids(k) (ascending) of the record array that starts at byte offset off.
  subroutine transfer(fh, off, n, gids, rec, write, ierr)
    type(MPI_File), intent(inout) :: fh
    integer(MPI_OFFSET_KIND), intent(in) :: off
    integer, intent(in) :: n
    integer(i8), intent(in) :: gids(:)
    real(wp), intent(inout) :: rec(:, :)
    logical, intent(in) :: write
    integer, intent(out) :: ierr
    integer, allocatable :: lens(:)
    integer(MPI_ADDRESS_KIND), allocatable :: disp(:)
    type(MPI_Datatype) :: view
    integer :: k, runs, e
    ! contiguous runs of global indices
    allocate(lens(size(gids)), disp(size(gids)))
    runs = 0
    do k = 1, size(gids)
      if (k > 1) then
        if (gids(k) == gids(k - 1) + 1) then
          lens(runs) = lens(runs) + n
          cycle
        end if
      end if
      runs = runs + 1
      lens(runs) = n
      disp(runs) = int(gids(k), MPI_ADDRESS_KIND)*8*n
    end do
    call MPI_Type_create_hindexed(runs, lens(1:runs), disp(1:runs), MPI_DOUBLE_PRECISION, view, &
                                  ierr)
    call MPI_Type_commit(view, e)
    ierr = max(ierr, e)
    call MPI_File_set_view(fh, off, MPI_DOUBLE_PRECISION, view, 'native', MPI_INFO_NULL, e)
    ierr = max(ierr, e)
    if (write) then
      call MPI_File_write_all(fh, rec, n*size(gids), MPI_DOUBLE_PRECISION, MPI_STATUS_IGNORE, e)
    else
      call MPI_File_read_all(fh, rec, n*size(gids), MPI_DOUBLE_PRECISION, MPI_STATUS_IGNORE, e)
    end if
    ierr = max(ierr, e)
    call MPI_Type_free(view, e)
    ierr = max(ierr, e)
  end subroutine transfer

  pure function header_ints(h) result(v)
    type(checkpoint_header_t), intent(in) :: h
    integer(i8) :: v(n_header)
    v = 0
    v(1:16) = [checkpoint_magic, h%version, h%nx, h%ny, h%n_state, h%nonlinear, h%depth, &
               h%verlet, h%step, h%n_samples, h%n_frames, h%n_ranks, h%model_hash, h%warned, &
               h%n_nodes, h%n_cells]
  end function header_ints

  pure function header_reals(h) result(v)
    type(checkpoint_header_t), intent(in) :: h
    real(wp) :: v(n_header)
    v = 0.0_wp
    v(1:7) = [h%t, h%dt, h%e0, h%e_scale, h%last_balance, h%w_ext, h%w_damp]
  end function header_reals
end module iem_checkpoint
