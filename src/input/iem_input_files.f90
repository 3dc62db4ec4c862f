!> The file rules of a run, checked on rank 0 before anything is written: every file to be
!> written (output, its .xmf sidecar, the checkpoint and its temporary) has a name the file
!> system, MPI-IO and HDF5 can take, an existing writable folder, is a regular file or absent,
!> and differs from every other file of the run (input, restart and the image of a cell map
!> included) after links, '.' and '..' are resolved. docs/output.md, "Files", states the rules.
module iem_input_files
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Bcast, MPI_INTEGER, MPI_CHARACTER
  use iem_config, only: config_t
  use iem_strings, only: itoa
  use iem_paths, only: path_kind, folder_writable, file_readable, resolved_path, folder_of, &
                       name_of, path_none, path_file, path_folder, path_special, name_max, &
                       path_max, mpiio_path_max
  use iem_xdmf, only: xdmf_path_of
  implicit none
  private
  public :: check_files, checkpoint_temp_of, bcast_message

contains

  !> The temporary name a checkpoint is written under before it is renamed into place.
  pure function checkpoint_temp_of(path) result(tmp)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: tmp
    tmp = path//'.tmp'
  end function checkpoint_temp_of

  !> Rank 0 checks every file the run reads or writes against the rules; collective; stat /= 0
  !> and the same msg on every rank when one is broken.
  subroutine check_files(cfg, comm, stat, msg)
    type(config_t), intent(in) :: cfg
    type(MPI_Comm), intent(in) :: comm
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer :: rank
    call MPI_Comm_rank(comm, rank)
    msg = ''
    if (rank == 0) call check_on_root(cfg, msg)
    call bcast_message(msg, comm)
    stat = merge(1, 0, len(msg) > 0)
    if (stat /= 0) msg = trim(cfg%input_file)//': '//msg
  end subroutine check_files

  subroutine check_on_root(cfg, msg)
    type(config_t), intent(in) :: cfg
    character(len=:), allocatable, intent(inout) :: msg
    character(len=:), allocatable :: out, xmf, chk, tmp, rst, inp, img
    character(len=path_max) :: names(6), resolved(6)
    character(len=*), parameter :: what(6) = [character(len=31) :: 'the input file', &
      'output_file', "the output's sidecar", 'checkpoint_file', &
      "the checkpoint's temporary file", 'restart']
    character(len=*), parameter :: vars(6) = [character(len=15) :: '', 'output_file', &
      'output_file', 'checkpoint_file', 'checkpoint_file', 'restart']
    logical :: restart, static
    integer :: i, j

    out = trim(cfg%run%output_file)
    xmf = xdmf_path_of(out)
    chk = trim(cfg%run%checkpoint_file)
    tmp = checkpoint_temp_of(chk)
    rst = trim(cfg%run%restart)
    inp = trim(cfg%input_file)
    restart = len(rst) > 0
    static = cfg%run%analysis == 'static'

    ! the files written, with the variable that names each
    call writable('output_file', out, out)
    if (len(msg) > 0) return
    call writable('output_file', out, xmf)
    if (len(msg) > 0) return
    if (.not. static) then
      call writable('checkpoint_file', chk, chk)
      if (len(msg) > 0) return
      call writable('checkpoint_file', chk, tmp)
      if (len(msg) > 0) return
    end if

    if (restart .and. len(rst) > mpiio_path_max) then
      call set("&run: restart = '"//rst//"': the path is "//itoa(len(rst))//' characters '// &
               'long; at most '//itoa(mpiio_path_max)//' are allowed for a file read through '// &
               'MPI-IO (give a shorter or relative path)')
      return
    else if (restart) then
      select case (path_kind(rst))
      case (path_file)
        if (.not. file_readable(rst)) call set("&run: restart = '"//rst//"': it is not readable")
      case (path_none)
        call set("&run: restart = '"//rst//"': no such file")
      case (path_folder)
        call set("&run: restart = '"//rst//"': it is a folder, not a checkpoint file")
      case (path_special)
        call set("&run: restart = '"//rst//"': it is not a regular file (a device, pipe "// &
                 "or socket)")
      case default
        call set("&run: restart = '"//rst//"': it cannot be looked at (a dangling link, or "// &
                 "no permission)")
      end select
      if (len(msg) > 0) return
      if (path_kind(out) == path_none) then
        call set("&run: output_file = '"//out//"' does not exist: a restart appends to the "// &
                 "output of the run it continues")
        return
      end if
    else if (.not. cfg%run%overwrite) then
      if (path_kind(out) /= path_none) then
        call set("&run: output_file = '"//out//"' exists; set overwrite = .true. to replace it")
        return
      else if (path_kind(xmf) /= path_none) then
        call set("&run: output_file = '"//out//"': its sidecar '"//xmf//"' exists; set "// &
                 "overwrite = .true. to replace it")
        return
      end if
    end if

    ! all distinct after resolution (the restart file may be the checkpoint file: continuing
    ! from a checkpoint and writing the next ones to the same name is the usual case)
    names = [character(len=path_max) :: inp, out, xmf, chk, tmp, rst]
    do i = 1, 6
      resolved(i) = ''
      if (len_trim(names(i)) == 0) cycle
      if (static .and. (i == 4 .or. i == 5)) cycle
      resolved(i) = resolved_path(trim(names(i)))
    end do
    do i = 2, 6
      if (len_trim(resolved(i)) == 0) cycle
      do j = 1, i - 1
        if (len_trim(resolved(j)) == 0) cycle
        if (i == 6 .and. j == 4) cycle
        if (resolved(i) == resolved(j)) then
          call set('&run: '//trim(vars(i))//" = '"//trim(names(i))//"' is the same file as "// &
                   trim(what(j))//" '"//trim(names(j))//"' ("//trim(resolved(i))//"); "// &
                   'the input, output, sidecar, checkpoint and restart files must be distinct')
          return
        end if
      end do
    end do
    ! the image of a cell map is read in the set-up: no file the run writes may be it
    if (len_trim(cfg%geometry%image) > 0) then
      img = resolved_path(trim(cfg%geometry%image))
      do i = 2, 5
        if (len_trim(resolved(i)) == 0) cycle
        if (trim(resolved(i)) == img) then
          call set("&geometry: image = '"//trim(cfg%geometry%image)//"' is the same file as "// &
                   trim(what(i))//" '"//trim(names(i))//"' ("//img//'); a run must not '// &
                   'write over its image')
          return
        end if
      end do
    end if

  contains

    subroutine set(text)
      character(len=*), intent(in) :: text
      msg = text
    end subroutine set

    !> Rules for one file to be written, named by variable var = value.
    subroutine writable(var, value, path)
      character(len=*), intent(in) :: var, value, path
      character(len=:), allocatable :: head, folder
      head = '&run: '//var//" = '"//value//"'"
      if (path /= value) head = head//' (writes '''//path//''')'
      folder = folder_of(path)
      if (len(name_of(path)) == 0) then
        call set(head//': names a folder, not a file')
      else if (len(name_of(path)) > name_max) then
        call set(head//': the file name is '//itoa(len(name_of(path)))//' characters long;'// &
                 ' at most '//itoa(name_max)//' are allowed')
      else if (len(path) > min(path_max, mpiio_path_max) .and. path /= xmf) then
        call set(head//': the path is '//itoa(len(path))//' characters long; at most '// &
                 itoa(mpiio_path_max)//' are allowed for a file written through MPI-IO '// &
                 '(give a shorter or relative path)')
      else if (len(path) > path_max) then
        call set(head//': the path is '//itoa(len(path))//' characters long; at most '// &
                 itoa(path_max)//' are allowed')
      else if (path_kind(folder) == path_none) then
        call set(head//": its folder does not exist ('"//folder//"')")
      else if (path_kind(folder) /= path_folder) then
        call set(head//": '"//folder//"' is not a folder")
      else if (.not. folder_writable(folder)) then
        call set(head//": its folder '"//folder//"' is not writable")
      else
        select case (path_kind(path))
        case (path_none, path_file)
          continue
        case (path_folder)
          call set(head//': it is a folder')
        case (path_special)
          call set(head//': it is not a regular file (a device, pipe or socket)')
        case default
          call set(head//': it cannot be looked at (a dangling link, or no permission)')
        end select
      end if
    end subroutine writable
  end subroutine check_on_root

  !> Broadcast rank 0's message (possibly empty) to every rank.
  subroutine bcast_message(msg, comm)
    character(len=:), allocatable, intent(inout) :: msg
    type(MPI_Comm), intent(in) :: comm
    integer :: n(1), rank
    call MPI_Comm_rank(comm, rank)
    n(1) = 0
    if (rank == 0) n(1) = len(msg)
    call MPI_Bcast(n, 1, MPI_INTEGER, 0, comm)
    if (rank /= 0) then
      if (allocated(msg)) deallocate(msg)
      allocate(character(len=n(1)) :: msg)
    end if
    if (n(1) > 0) call MPI_Bcast(msg, n(1), MPI_CHARACTER, 0, comm)
  end subroutine bcast_message
end module iem_input_files
