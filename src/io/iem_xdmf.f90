!> XDMF sidecar that lets ParaView open an iem HDF5 output file (see docs/output.md).
!>
!> Every dataset the sidecar can list is one entry of `xdmf_fields`: its name, whether it is
!> written in every frame group or once in /mesh, its centre and its components. A frame lists
!> the per-frame fields its group holds (a bit mask per frame, `xdmf_field_bit`), every grid the
!> /mesh fields the file holds.
module iem_xdmf
  use iem_kinds, only: wp, i8
  use iem_strings, only: itoa
  implicit none
  private
  public :: xdmf_write, xdmf_frame_name, xdmf_path_of, xdmf_field_index, xdmf_field_bit

  !> A 2D vector field <name> (n, 2) of a frame has a virtual companion <name>//this (n, 3),
  !> z = 0, written with it; the sidecar lists that one, a vector to every ParaView reader.
  character(len=*), parameter, public :: xdmf_xyz_suffix = '_xyz'

  !> One dataset the sidecar can list.
  type, public :: xdmf_field_t
    !> dataset name, in /frames/frame_NNNNNN (per_frame) or in /mesh
    character(len=16) :: name
    logical :: per_frame
    !> 'Node' (n_nodes entries) or 'Cell' (n_cells entries, cell order of /mesh/cells)
    character(len=4) :: center
    !> 2: a 2D vector, (n, 2) in the file, listed through its (n, 3) view; 1: a scalar
    integer :: ncomp
    !> XDMF NumberType ('Float' or 'Int') and Precision (bytes) of the dataset
    character(len=5) :: number_type
    integer :: precision
  end type xdmf_field_t

  !> Everything a frame or the mesh may hold besides the mesh itself. A new field is one entry
  !> here (at most bit_size(0) entries); the writer sets its bit where it writes it.
  type(xdmf_field_t), parameter, public :: xdmf_fields(5) = [ &
    xdmf_field_t('displacement', .true., 'Node', 2, 'Float', 8), &
    xdmf_field_t('velocity', .true., 'Node', 2, 'Float', 8), &
    xdmf_field_t('nonlinearity', .true., 'Cell', 1, 'Float', 8), &
    xdmf_field_t('material', .false., 'Cell', 1, 'Int', 4), &
    xdmf_field_t('damage', .true., 'Cell', 1, 'Float', 8)]

contains

  !> Name of the HDF5 group of the frame with 0-based index `index`: frame_000000, ...
  pure function xdmf_frame_name(index) result(name)
    integer(i8), intent(in) :: index
    character(len=:), allocatable :: name
    character(len=32) :: buf

    write (buf, '(a, i0.6)') 'frame_', index
    name = trim(buf)
  end function xdmf_frame_name

  !> Path of the sidecar of `h5_path`: the extension of the file name replaced by `.xmf`.
  pure function xdmf_path_of(h5_path) result(xmf_path)
    character(len=*), intent(in) :: h5_path
    character(len=:), allocatable :: xmf_path
    integer :: dot, slash

    slash = index(h5_path, '/', back=.true.)
    dot = index(h5_path, '.', back=.true.)
    ! A dot in a folder name or a leading dot (hidden file) is no extension; a file already
    ! named .xmf keeps its name and gets a second extension, so the sidecar never replaces it.
    ! (nested: Fortran's .and. may evaluate both operands, and h5_path(dot:) needs dot >= 1)
    xmf_path = h5_path//'.xmf'
    if (dot > slash + 1) then
      if (h5_path(dot:) /= '.xmf') xmf_path = h5_path(:dot - 1)//'.xmf'
    end if
  end function xdmf_path_of

  !> Index of the field `name` in xdmf_fields, 0 if the sidecar does not know it.
  pure integer function xdmf_field_index(name) result(k)
    character(len=*), intent(in) :: name

    do k = 1, size(xdmf_fields)
      if (xdmf_fields(k)%name == name) return
    end do
    k = 0
  end function xdmf_field_index

  !> Bit mask of the field `name` (0 if the sidecar does not know it), to be ORed into the
  !> mask of a frame or of the mesh.
  pure integer function xdmf_field_bit(name) result(bit)
    character(len=*), intent(in) :: name
    integer :: k

    k = xdmf_field_index(name)
    bit = 0
    if (k > 0) bit = ibset(0, k - 1)
  end function xdmf_field_bit

  !> Writes the sidecar: one grid per frame in a temporal collection, or the bare mesh.
  subroutine xdmf_write(xmf_path, h5_name, n_nodes, n_cells, times, frame_fields, mesh_fields, &
      stat, msg)
    ! h5_name: the HDF5 file as seen from the sidecar's folder; times(k): time of frame k-1;
    ! frame_fields(k): bits (xdmf_field_bit) of the per-frame fields frame k-1 holds;
    ! mesh_fields: bits of the /mesh fields of xdmf_fields the file holds.
    character(len=*), intent(in) :: xmf_path, h5_name
    integer(i8), intent(in) :: n_nodes, n_cells
    real(wp), intent(in) :: times(:)
    integer, intent(in) :: frame_fields(:), mesh_fields
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=:), allocatable :: h5, frame
    character(len=256) :: iom
    character(len=32) :: tbuf
    integer :: unit, k

    stat = 0
    msg = ''
    if (size(frame_fields) /= size(times)) then
      stat = 1
      msg = 'iem_xdmf: '//xmf_path//': frame_fields and times differ in size'
      return
    end if
    h5 = xml_escape(h5_name)
    open (newunit=unit, file=xmf_path, status='replace', action='write', form='formatted', &
          iostat=stat, iomsg=iom)
    if (stat /= 0) then
      msg = 'iem_xdmf: cannot open '//xmf_path//' for writing: '//trim(iom)
      return
    end if
    write (unit, '(a)', iostat=stat, iomsg=iom) '<?xml version="1.0" ?>', &
      '<Xdmf Version="3.0">', '  <Domain>'
    if (size(times) == 0) then
      if (stat == 0) write (unit, '(a)', iostat=stat, iomsg=iom) &
        '    <Grid Name="mesh" GridType="Uniform">'
      if (stat == 0) call write_grid_items(unit, '      ', '', 0, stat, iom)
      if (stat == 0) write (unit, '(a)', iostat=stat, iomsg=iom) '    </Grid>'
    else
      if (stat == 0) write (unit, '(a)', iostat=stat, iomsg=iom) &
        '    <Grid Name="iem" GridType="Collection" CollectionType="Temporal">'
      do k = 1, size(times)
        if (stat /= 0) exit
        frame = xdmf_frame_name(int(k - 1, i8))
        write (tbuf, '(es24.16e3)') times(k)
        write (unit, '(a)', iostat=stat, iomsg=iom) &
          '      <Grid Name="'//frame//'" GridType="Uniform">', &
          '        <Time Value="'//trim(adjustl(tbuf))//'"/>'
        if (stat == 0) call write_grid_items(unit, '        ', frame, frame_fields(k), stat, iom)
        if (stat == 0) write (unit, '(a)', iostat=stat, iomsg=iom) '      </Grid>'
      end do
      if (stat == 0) write (unit, '(a)', iostat=stat, iomsg=iom) '    </Grid>'
    end if
    if (stat == 0) write (unit, '(a)', iostat=stat, iomsg=iom) '  </Domain>', '</Xdmf>'
    if (stat /= 0) then
      msg = 'iem_xdmf: cannot write '//xmf_path//': '//trim(iom)
      close (unit, iostat=k)
      return
    end if
    close (unit, iostat=stat, iomsg=iom)
    if (stat /= 0) msg = 'iem_xdmf: cannot close '//xmf_path//': '//trim(iom)

  contains

    !> Topology, geometry, the /mesh fields and the fields of frame `group` (bits `fields`).
    subroutine write_grid_items(u, ind, group, fields, ios, iomsg)
      integer, intent(in) :: u, fields
      character(len=*), intent(in) :: ind, group
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: iomsg
      integer :: f

      write (u, '(a)', iostat=ios, iomsg=iomsg) &
        ind//'<Topology TopologyType="Quadrilateral" NumberOfElements="'//itoa(n_cells)//'">', &
        ind//'  '//data_item(itoa(n_cells)//' 4', 'Int', 8, '/mesh/cells'), &
        ind//'</Topology>', &
        ind//'<Geometry GeometryType="XY">', &
        ind//'  '//data_item(itoa(n_nodes)//' 2', 'Float', 8, '/mesh/coordinates'), &
        ind//'</Geometry>'
      do f = 1, size(xdmf_fields)
        if (ios /= 0) return
        if (xdmf_fields(f)%per_frame) then
          if (len(group) == 0 .or. .not. btest(fields, f - 1)) cycle
          call write_attribute(u, ind, xdmf_fields(f), '/frames/'//group//'/', ios, iomsg)
        else
          if (.not. btest(mesh_fields, f - 1)) cycle
          call write_attribute(u, ind, xdmf_fields(f), '/mesh/', ios, iomsg)
        end if
      end do
    end subroutine write_grid_items

    !> One attribute: field `fld` at the HDF5 path `where`//name.
    subroutine write_attribute(u, ind, fld, where, ios, iomsg)
      integer, intent(in) :: u
      character(len=*), intent(in) :: ind, where
      type(xdmf_field_t), intent(in) :: fld
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: iomsg
      character(len=:), allocatable :: name, n

      name = trim(fld%name)
      n = itoa(merge(n_nodes, n_cells, fld%center == 'Node'))
      if (fld%ncomp == 2) then
        ! ParaView's Xdmf3 readers (its default for .xmf) take only 3 components as a vector
        ! and do not evaluate XDMF functions (measured with ParaView 5.11): the (n, 3) view.
        write (u, '(a)', iostat=ios, iomsg=iomsg) &
          ind//'<Attribute Name="'//name//'" AttributeType="Vector" Center="'// &
          trim(fld%center)//'">', &
          ind//'  '//data_item(n//' 3', fld%number_type, fld%precision, &
                               where//name//xdmf_xyz_suffix), &
          ind//'</Attribute>'
      else
        write (u, '(a)', iostat=ios, iomsg=iomsg) &
          ind//'<Attribute Name="'//name//'" AttributeType="Scalar" Center="'// &
          trim(fld%center)//'">', &
          ind//'  '//data_item(n, fld%number_type, fld%precision, where//name), &
          ind//'</Attribute>'
      end if
    end subroutine write_attribute

    !> A DataItem that reads dataset `path` of the HDF5 file.
    pure function data_item(dims, number_type, precision, path) result(s)
      character(len=*), intent(in) :: dims, number_type, path
      integer, intent(in) :: precision
      character(len=:), allocatable :: s

      s = '<DataItem Dimensions="'//dims//'" NumberType="'//trim(number_type)// &
          '" Precision="'//itoa(int(precision, i8))//'" Format="HDF">'//h5//':'//path// &
          '</DataItem>'
    end function data_item
  end subroutine xdmf_write


  !> `text` with the XML special characters replaced by entities.
  pure function xml_escape(text) result(s)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: s
    integer :: k

    s = ''
    do k = 1, len(text)
      select case (text(k:k))
      case ('&')
        s = s//'&amp;'
      case ('<')
        s = s//'&lt;'
      case ('>')
        s = s//'&gt;'
      case ('"')
        s = s//'&quot;'
      case default
        s = s//text(k:k)
      end select
    end do
  end function xml_escape
end module iem_xdmf
